# tirstrain.process and tirstrain.read_result on a small synthetic trial (tirstrain synth), checked against
# the trial's truth; errors carry the CLI's messages.
import math

import h5py
import numpy as np
import pytest

from conftest import cli_error

import tirstrain

# A 4-frame, 200x160 trial with a ~60 px contact: a = (3 P R / (4 E*))^(1/3) = 1.16 mm at 52 px/mm.
SCENE = """
calibration: {px_per_mm: 52, ridge_period_mm: 0.45, ridge_polarity: dark}
tissue: {E_Pa: 1.0e6, nu: 0.4, depth_m: 0.002}
compute: [contact, tracking]
synthesis:
  seed: 3
  image: {width_px: 200, height_px: 160, bit_depth: 8}
  timing: {frames: 4, frame_rate_hz: 100}
  contact: {shape: hertz, normal_N: 0.5, radius_m: 0.005}
  loading: {field: cattaneo_mindlin, friction: 1.0, direction_deg: 0, plate_speed_mm_s: 5.0}
"""


@pytest.fixture(scope="module")
def trial(tmp_path_factory, cli):
    folder = tmp_path_factory.mktemp("trial")
    (folder / "scene.yaml").write_text(SCENE)
    r = cli("synth", "--scene", folder / "scene.yaml", "--out", folder / "synth")
    assert r.returncode == 0, r.stderr
    return folder / "synth"


def test_process_returns_the_summary_and_result_reads_back(trial, tmp_path):
    out = tmp_path / "out"
    summary = tirstrain.process(trial, out, overlay="none", quiet=True)
    assert summary == __import__("json").loads((out / "summary.json").read_text())
    assert summary["frames"]["total"] == 4 and summary["complete"]
    result = tirstrain.read_result(out / "result.h5")
    truth = tirstrain.read_result(trial / "truth.h5")
    with h5py.File(out / "result.h5") as f:
        assert set(result) == {name for name, obj in _datasets(f)}
        for name, obj in _datasets(f):
            assert result[name].dtype == obj.dtype
            np.testing.assert_array_equal(result[name], obj[()])
    # The measured contact area against the rendered contact mask (52 px/mm).
    area = result["/contact/area_mm2"]
    assert area.shape == (4,)
    np.testing.assert_allclose(area, truth["/contact/mask"].sum(axis=(1, 2)) / 52.0**2, rtol=0.1)


def _datasets(f):
    found = []
    f.visititems(lambda name, obj: found.append(("/" + name, obj)) if isinstance(obj, h5py.Dataset) else None)
    return found


def test_read_result_keeps_dtypes(tmp_path):
    path = tmp_path / "x.h5"
    with h5py.File(path, "w") as f:
        f["/a/b"] = np.arange(6, dtype=np.int8).reshape(2, 3)
        f["/c"] = np.array([1.5, math.nan], dtype=np.float32)
    r = tirstrain.read_result(path)
    assert r["/a/b"].dtype == np.int8 and r["/a/b"].tolist() == [[0, 1, 2], [3, 4, 5]]
    assert r["/c"].dtype == np.float32 and r["/c"][0] == 1.5 and math.isnan(r["/c"][1])


def test_errors_name_the_input(tmp_path):
    # tirstrain process prints the same; test_track_reads_a_frames_folder compares a message with the CLI.
    missing = tmp_path / "no_such_recording"
    with pytest.raises(tirstrain.Error) as e:
        tirstrain.process(missing, tmp_path / "out", quiet=True)
    assert str(e.value) == f"{missing}: no such file or folder"
    assert not (tmp_path / "out").exists()
    with pytest.raises(tirstrain.Error, match="none.h5: no such file"):
        tirstrain.read_result(tmp_path / "none.h5")
    (tmp_path / "text.h5").write_text("not HDF5\n")
    with pytest.raises(tirstrain.Error, match="cannot read HDF5 file"):
        tirstrain.read_result(tmp_path / "text.h5")
    # Where the command line names its option, the module names the keyword argument.
    with pytest.raises(tirstrain.Error) as e:
        tirstrain.process(missing, tmp_path / "out", preset="fastest", quiet=True)
    assert "--" not in str(e.value) and "preset" in str(e.value)


def test_a_bad_preset_names_the_keyword_not_the_scene(trial, tmp_path):
    # The trial has a scene.yaml beside its frames; the bad value is the keyword's, not the scene's.
    for keyword, value in (("preset", "bogus"), ("segmentation", "sharpest")):
        with pytest.raises(tirstrain.Error) as e:
            tirstrain.process(trial, tmp_path / "out", quiet=True, **{keyword: value})
        assert f"'{keyword}': '{value}' is not one of" in str(e.value), str(e.value)
        assert "scene.yaml" not in str(e.value)
    assert not (tmp_path / "out").exists()


def test_track_reads_a_frames_folder(trial, tmp_path, cli):
    truth = tirstrain.read_result(trial / "truth.h5")
    # The box inside the rendered contact (outside it, the dots printed on the glass move with the plate).
    ys, xs = np.nonzero(truth["/contact/mask"][0])
    box = (int(xs.min()) + 20, int(ys.min()) + 20, int(xs.max() - xs.min()) - 40, int(ys.max() - ys.min()) - 40)
    reference, position, status = tirstrain.track(trial, grid_px=12, roi=box)
    assert position.shape == (4, len(reference), 2) and status.shape == (4, len(reference))
    alive = (status[-1] >= 0) & (status[-1] < 10)
    assert alive.sum() >= 4
    # Against the rendered field (truth grid, bilinear between its nodes): the tracker is good to ~0.03 px here.
    gx, gy, u = truth["/grid/x_px"], truth["/grid/y_px"], truth["/field/displacement_px"][-1]
    for k in np.nonzero(alive)[0]:
        x, y = reference[k]
        i, j = np.searchsorted(gx, x) - 1, np.searchsorted(gy, y) - 1
        fx, fy = (x - gx[i]) / (gx[i + 1] - gx[i]), (y - gy[j]) / (gy[j + 1] - gy[j])
        expected = (u[j, i] * (1 - fx) * (1 - fy) + u[j, i + 1] * fx * (1 - fy) + u[j + 1, i] * (1 - fx) * fy +
                    u[j + 1, i + 1] * fx * fy)
        np.testing.assert_allclose(position[-1][k] - reference[k], expected, atol=0.1)
    assert np.abs(u).max() > 3.0  # the field moved the skin by pixels, not hundredths
    missing = tmp_path / "no_frames_here"
    with pytest.raises(tirstrain.Error) as e:
        tirstrain.track(missing, grid_px=20)
    assert str(e.value) == cli_error(cli("track", missing, "--grid", 20, "--out", tmp_path / "t.csv"))
