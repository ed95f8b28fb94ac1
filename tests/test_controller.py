"""The control law by hand: feedforward + PID, saturation, anti-windup, residual and override."""


from __future__ import annotations

import numpy as np

from mjtraj.core.controller import PIDGains, control_law


def test_control_law_by_hand():
    gains = PIDGains.create([10.0, 20.0], [1.0, 2.0], [3.0, 4.0], 2)
    e, ed, I = np.array([[0.1, -0.2]]), np.array([[1.0, 0.5]]), np.array([[0.01, 0.02]])
    out = control_law(e, ed, I, np.array([[5.0, 70.0]]), gains, np.array([60.0, 60.0]), 0.02)
    # I = [0.012, 0.016]; fb = [1 + 0.012 + 3, -4 + 0.032 + 2] = [4.012, -1.968]
    np.testing.assert_allclose(out.integral, [[0.012, 0.016]], atol=1e-15)
    np.testing.assert_allclose(out.tau_fb, [[4.012, -1.968]], atol=1e-12)
    np.testing.assert_allclose(out.dtau, [[9.012, 60.0]], atol=1e-12)
    np.testing.assert_array_equal(out.saturated, [[False, True]])
    clamp = control_law(e, ed, I, np.array([[5.0, 70.0]]), gains, np.array([60.0, 60.0]), 0.02, anti_windup="clamp")
    np.testing.assert_allclose(clamp.integral, [[0.012, 0.02]], atol=1e-15)  # frozen on the saturated joint
    torque = control_law(e, ed, I, np.zeros((1, 2)), gains, np.array([60.0, 60.0]), 0.02,
                         override=np.array([[-80.0, 3.0]]))
    np.testing.assert_array_equal(torque.dtau, [[-60.0, 3.0]])
    np.testing.assert_array_equal(torque.tau_fb, [[0.0, 0.0]])

