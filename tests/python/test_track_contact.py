# tirstrain.track on a texture shifted by a known sub-pixel amount, tirstrain.segment on a drawn contact.
import math

import numpy as np
import pytest

import tirstrain


def texture(shape, dx, dy, seed=7):
    """A smooth random texture (sum of plane waves, periods 6-20 px), shifted by (dx, dy) exactly."""
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:shape[0], 0:shape[1]].astype(np.float64)
    image = np.zeros(shape)
    for _ in range(24):
        k = 2 * math.pi / rng.uniform(6.0, 20.0)
        a = rng.uniform(0, 2 * math.pi)
        image += np.cos(k * (math.cos(a) * (x - dx) + math.sin(a) * (y - dy)) + rng.uniform(0, 2 * math.pi))
    return (0.5 + 0.07 * image).clip(0.0, 1.0).astype(np.float32)


SHIFTS = [(0.0, 0.0), (0.8, -0.4), (1.6, -0.8)]


def test_track_recovers_a_rigid_shift():
    frames = [texture((96, 112), dx, dy) for dx, dy in SHIFTS]
    reference, position, status = tirstrain.track(frames, grid_px=16)
    k = reference.shape[0]
    assert reference.shape == (k, 2) and k >= 4
    assert position.shape == (3, k, 2) and status.shape == (3, k)
    # Grid points without a full subset of texture would be retired at once (status >= 10).
    started = status[0] < 10
    np.testing.assert_allclose(position[0][started], reference[started], atol=1e-9)
    alive = (status[-1] >= 0) & (status[-1] < 10)
    assert (alive == started).all()
    for (dx, dy), p in zip(SHIFTS, position):
        d = p[alive] - reference[alive]
        np.testing.assert_allclose(np.median(d, axis=0), [dx, dy], atol=0.03)
    assert np.isnan(position[-1][~alive]).all()


def test_a_retired_track_carries_its_reason_once_then_minus_one():
    # The left half of the texture goes flat from frame 2 on: the tracks there are retired in frame 2 with
    # their reason (>= 10) and are -1 in frame 3, as /tracks/status in result.h5.
    frames = [texture((96, 112), 0.4 * i, 0.0) for i in range(4)]
    for f in frames[2:]:
        f[:, :56] = 0.5
    reference, position, status = tirstrain.track(frames, grid_px=12)
    retired_at_2 = (status[1] >= 0) & (status[1] < 10) & (status[2] >= 10)
    assert retired_at_2.sum() >= 3, status
    assert (status[3, retired_at_2] == -1).all()
    assert np.isnan(position[3][retired_at_2]).all()
    assert not (status[3] >= 10).any() or (status[2, status[3] >= 10] < 10).all()


def test_track_accepts_uint8_and_roi():
    frames = [np.round(255 * texture((96, 112), dx, dy)).astype(np.uint8) for dx, dy in SHIFTS[:2]]
    reference, position, status = tirstrain.track(frames, grid_px=12, roi=(40, 20, 60, 60))
    assert ((reference >= [40, 20]) & (reference <= [99, 79])).all()
    alive = (status[-1] >= 0) & (status[-1] < 10)
    np.testing.assert_allclose(np.median(position[1][alive] - reference[alive], axis=0), SHIFTS[1], atol=0.05)
    # A 3-D array [N, H, W] is its N frames.
    stacked = tirstrain.track(np.stack(frames), grid_px=12, roi=(40, 20, 60, 60))
    np.testing.assert_array_equal(stacked[1], position)


def test_track_errors_name_the_frame():
    good = texture((64, 64), 0, 0)
    with pytest.raises(tirstrain.Error, match=r"frames\[1\].*float64"):
        tirstrain.track([good, good.astype(np.float64)], grid_px=8)
    with pytest.raises(tirstrain.Error, match="does not fit in the 64x64 frame"):
        tirstrain.track([good], grid_px=8, roi=(50, 50, 30, 30))
    # A NaN pixel would spread through the filters and retire every track: named instead.
    bad = good.copy()
    bad[3, 5] = np.nan
    with pytest.raises(tirstrain.Error, match=r"frames\[1\].*pixel \(x 5, y 3\) is not a finite number"):
        tirstrain.track([good, bad], grid_px=8)
    bad[3, 5] = np.inf
    with pytest.raises(tirstrain.Error, match="not a finite number"):
        tirstrain.segment(bad, px_per_mm=52.0)
    with pytest.raises(tirstrain.Error, match="px_per_mm.*expected a number"):
        tirstrain.segment(good, px_per_mm="x")


def test_segment_finds_a_drawn_contact():
    # A 5 px/mm-free drawing: ridges of period 10 px inside an ellipse, flat grey outside.
    h, w, cx, cy, ax, by = 240, 280, 150.0, 118.0, 70.0, 52.0
    y, x = np.mgrid[0:h, 0:w].astype(np.float64)
    inside = ((x - cx) / ax) ** 2 + ((y - cy) / by) ** 2 <= 1.0
    rng = np.random.default_rng(1)
    image = 0.35 + 0.01 * rng.standard_normal((h, w))
    image[inside] += 0.25 * (1 + np.cos(2 * math.pi * (x[inside] + 0.3 * y[inside]) / 10.0)) / 2
    r = tirstrain.segment(image.astype(np.float32), px_per_mm=20.0, ridge_period_px=10.0)
    assert r["status_text"] == "ok"
    e = r["ellipse"]
    assert e["cx_px"] == pytest.approx(cx, abs=3.0)
    assert e["cy_px"] == pytest.approx(cy, abs=3.0)
    assert e["semi_major_px"] == pytest.approx(ax, rel=0.06)
    assert e["semi_minor_px"] == pytest.approx(by, rel=0.06)
    assert r["area_mm2"] == pytest.approx(math.pi * ax * by / 400.0, rel=0.1)
    assert r["hull_px"].shape == (50, 2)
    with pytest.raises(tirstrain.Error, match="unknown segmentation option"):
        tirstrain.segment(image.astype(np.float32), px_per_mmm=20.0)
