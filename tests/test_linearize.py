"""Linearisation by finite differences against closed forms, and ZOH against scipy."""


from __future__ import annotations

import numpy as np
import scipy.signal

from mjtraj.core.gains import mass_matrix
from mjtraj.core.linearize import discretize_zoh, linearize


def test_linearization_at_rest(model):
    q_bar = np.array([0.5, -1.07, 0.5])
    A, B = linearize(model, q_bar)
    np.testing.assert_allclose(A, np.block([[np.zeros((3, 3)), np.eye(3)], [np.zeros((3, 3)), np.zeros((3, 3))]]),
                               atol=1e-6)
    np.testing.assert_allclose(B, np.vstack([np.zeros((3, 3)), np.linalg.inv(mass_matrix(model, q_bar))]), atol=1e-6)


def test_zoh_matches_scipy(model, rng):
    A, B = linearize(model, [0.3, -1.0, 0.8], qd=[0.5, -0.4, 0.3], u=[5.0, -3.0, 2.0])
    Ad, Bd = discretize_zoh(A, B, 0.02)
    ref = scipy.signal.cont2discrete((A, B, np.eye(6), np.zeros((6, 3))), 0.02, method="zoh")
    np.testing.assert_allclose(Ad, ref[0], atol=1e-12)
    np.testing.assert_allclose(Bd, ref[1], atol=1e-12)

