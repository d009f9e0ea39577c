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


def test_errors_are_the_cli_messages(tmp_path, cli):
    missing = tmp_path / "no_such_recording"
    with pytest.raises(tirstrain.Error) as e:
        tirstrain.process(missing, tmp_path / "out", quiet=True)
    assert str(e.value) == cli_error(cli("process", missing, "--out", tmp_path / "out", "--quiet"))
    assert not (tmp_path / "out").exists()
    with pytest.raises(tirstrain.Error, match="cannot read HDF5 file"):
        tirstrain.read_result(tmp_path / "none.h5")
