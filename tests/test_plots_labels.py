"""Figure text that papers need: labels that never overlap, log axes in plain numbers."""

from __future__ import annotations

import itertools

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from mjtraj.study.plots import place_labels, plain_log_ticks  # noqa: E402


def test_labels_of_crowded_points_never_overlap_and_stay_inside():
    fig, ax = plt.subplots(figsize=(4, 3))
    xs = [1.0, 1.01, 1.02, 1.03, 1.05, 2.0, 2.02]
    ax.plot(xs, xs, "o")
    place_labels(ax, [(0, x, x, f"α={x:g} (a long label)") for x in xs], "C0")
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    boxes = [t.get_window_extent(renderer) for t in ax.texts]
    frame = ax.get_window_extent(renderer)
    assert 2 <= len(boxes) <= len(xs)  # crowded: some are left out rather than overlap
    for a, b in itertools.combinations(boxes, 2):
        assert not a.overlaps(b)
    for box in boxes:
        assert frame.x0 <= box.x0 and box.x1 <= frame.x1 and frame.y0 <= box.y0 and box.y1 <= frame.y1
    plt.close(fig)


def test_log_ticks_read_as_plain_numbers():
    fig, ax = plt.subplots()
    ax.plot([2.5, 12.0], [0.0015, 0.007])
    ax.set_xscale("log")
    ax.set_yscale("log")
    plain_log_ticks(ax)
    fig.canvas.draw()
    labels = [t.get_text() for t in ax.get_xticklabels(which="both") + ax.get_yticklabels(which="both")]
    shown = [text for text in labels if text]
    assert "10" in shown and "3" in shown and "0.002" in shown
    assert not any("times" in text or "^" in text for text in shown)
    plt.close(fig)
