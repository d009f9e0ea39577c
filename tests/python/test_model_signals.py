# tirstrain.cattaneo_mindlin against the closed forms of docs/model.md, and the signals functions against
# signals with known spectra, gains and recurrence.
import math

import numpy as np
import pytest

import tirstrain

CM = dict(normal_N=1.0, tangential_N=0.3, radius_m=0.01, young_Pa=1.0e6, poisson=0.4, friction=1.0)


def hertz_stick(p):
    """Contact radius a, stick radius c and the stick zone's rigid shift (Johnson 1985 §3.4, §7.2)."""
    e_star = p["young_Pa"] / (1.0 - p["poisson"] ** 2)
    a = (3.0 * p["normal_N"] * p["radius_m"] / (4.0 * e_star)) ** (1.0 / 3.0)
    g = p["young_Pa"] / (2.0 * (1.0 + p["poisson"]))
    ratio = p["tangential_N"] / (p["friction"] * p["normal_N"])
    c = a * (1.0 - ratio) ** (1.0 / 3.0)
    shift = 3.0 * p["friction"] * p["normal_N"] * (2.0 - p["poisson"]) / (16.0 * g * a) * (
        1.0 - (1.0 - ratio) ** (2.0 / 3.0))
    return a, c, shift


def test_cattaneo_mindlin_stick_zone_moves_rigidly():
    a, c, shift = hertz_stick(CM)
    r = np.linspace(0.0, 0.9 * c, 7)
    theta = np.linspace(0.0, 2.0 * math.pi, 7)
    x, y = r * np.cos(theta), r * np.sin(theta)
    f = tirstrain.cattaneo_mindlin(x, y, **CM)
    assert set(f) == {"ux_m", "uy_m", "Exx", "Eyy", "Exy", "energy_density_J_m3"}
    assert f["ux_m"].shape == x.shape
    # Inside the stick zone the surface translates by delta_x: no strain, no energy.
    np.testing.assert_allclose(f["ux_m"], shift, rtol=1e-9)
    np.testing.assert_allclose(f["uy_m"], 0.0, atol=1e-12 * shift)
    for key in ("Exx", "Eyy", "Exy", "energy_density_J_m3"):
        np.testing.assert_allclose(f[key], 0.0, atol=1e-12)
    # Turned by direction_rad, the shift follows; a 2-D grid keeps its shape.
    gx, gy = np.meshgrid(np.linspace(-0.5 * c, 0.5 * c, 3), np.linspace(-0.5 * c, 0.5 * c, 4))
    g = tirstrain.cattaneo_mindlin(gx, gy, **CM, direction_rad=math.pi / 2)
    assert g["uy_m"].shape == (4, 3)
    np.testing.assert_allclose(g["uy_m"], shift, rtol=1e-9)
    np.testing.assert_allclose(g["ux_m"], 0.0, atol=1e-9 * shift)


def test_cattaneo_mindlin_slips_outside_the_stick_zone():
    a, c, shift = hertz_stick(CM)
    f = tirstrain.cattaneo_mindlin(np.array([0.5 * (a + c), 3.0 * a]), np.array([0.0, 0.0]), **CM)
    # In the slip annulus the skin lags behind the stick zone and is compressed along x ahead of it
    # (ux decreasing with x); far away the displacement decays towards 0.
    assert 0.0 < f["ux_m"][0] < shift
    assert 0.0 < f["ux_m"][1] < f["ux_m"][0]
    assert f["Exx"][0] < 0.0
    assert f["energy_density_J_m3"][0] > 0.0


def test_cattaneo_mindlin_errors_name_the_argument():
    with pytest.raises(tirstrain.Error, match="tangential_N"):
        tirstrain.cattaneo_mindlin(np.zeros(1), np.zeros(1), **{**CM, "tangential_N": 2.0})
    with pytest.raises(tirstrain.Error, match="same shape"):
        tirstrain.cattaneo_mindlin(np.zeros(2), np.zeros(3), **CM)
    # None (NumPy makes it NaN) or a NaN point: named, not NaN fields back.
    with pytest.raises(tirstrain.Error, match=r"'x_m'.*point 0 is NaN \(or None\)"):
        tirstrain.cattaneo_mindlin(None, None, **CM)
    with pytest.raises(tirstrain.Error, match=r"'y_m'.*point 1 is NaN"):
        tirstrain.cattaneo_mindlin(np.zeros(2), np.array([0.0, None], dtype=float), **CM)


def test_psd_peak_and_power_of_a_sinusoid():
    fs, f0, amplitude = 1000.0, 50.0, 2.0
    t = np.arange(8000) / fs
    freq, psd = tirstrain.psd(amplitude * np.sin(2 * math.pi * f0 * t), sample_rate_Hz=fs, segment=1000)
    assert freq[1] - freq[0] == pytest.approx(1.0)
    assert freq[np.argmax(psd)] == pytest.approx(f0)
    # Density integrated over frequency = the variance A^2/2.
    assert np.sum(psd) * (freq[1] - freq[0]) == pytest.approx(amplitude**2 / 2, rel=1e-3)


def test_lowpass_keeps_the_slow_component():
    fs = 1000.0
    t = np.arange(2000) / fs
    slow = np.sin(2 * math.pi * 10 * t)
    y = tirstrain.filter(slow + 0.5 * np.sin(2 * math.pi * 200 * t), sample_rate_Hz=fs, lowpass_Hz=50.0)
    # filtfilt of a 4th-order Butterworth at 50 Hz: |H(10 Hz)|^2 = 0.99997, |H(200 Hz)|^2 = 1.5e-5.
    np.testing.assert_allclose(y[200:-200], slow[200:-200], atol=2e-3)
    with pytest.raises(tirstrain.Error, match="exactly one of lowpass_Hz"):
        tirstrain.filter(slow, sample_rate_Hz=fs)


def test_tf_of_a_pure_gain():
    rng = np.random.default_rng(3)
    x = rng.standard_normal(4096)
    h = tirstrain.tf(x, -2.5 * x, sample_rate_Hz=100.0, segment=256)
    np.testing.assert_allclose(h["gain"][1:], 2.5, rtol=1e-9)
    np.testing.assert_allclose(np.abs(h["phase_rad"][1:]), math.pi, rtol=1e-9)
    np.testing.assert_allclose(h["coherence"][1:], 1.0, rtol=1e-9)
    with pytest.raises(tirstrain.Error, match="segment must be at least 2 samples"):
        tirstrain.psd(x, sample_rate_Hz=100.0, segment=1)
    # A NaN sample is named, as the command line does, instead of giving spectra of zeros or NaN.
    gap = x.copy()
    gap[100] = np.nan
    for call in (lambda: tirstrain.tf(gap, x, sample_rate_Hz=100.0, segment=256),
                 lambda: tirstrain.psd(gap, sample_rate_Hz=100.0, segment=256),
                 lambda: tirstrain.rqa(gap[:500], dim=3, delay=2, threshold=0.5)):
        with pytest.raises(tirstrain.Error, match=r"sample 100 \(0-based\) is not a finite number"):
            call()


def test_rqa_of_a_periodic_signal():
    x = np.sin(2 * math.pi * np.arange(600) / 40.0)
    m = tirstrain.rqa(x, dim=2, delay=10, recurrence_rate=0.05)
    assert m["embedded_points"] == 590
    # The threshold is the smallest that reaches the rate; a periodic orbit recurs along diagonals, white
    # noise at the same rate hardly ever twice in a row.
    assert 0.05 <= m["recurrence_rate"] < 0.06
    assert m["determinism"] > 0.85
    noise = tirstrain.rqa(np.random.default_rng(1).standard_normal(600), dim=2, delay=10, recurrence_rate=0.05)
    assert noise["determinism"] < 0.2
    with pytest.raises(tirstrain.Error, match="exactly one of threshold"):
        tirstrain.rqa(x, dim=2, delay=10)
    with pytest.raises(tirstrain.Error, match="threshold.*must be at least 0"):
        tirstrain.rqa(x, dim=2, delay=10, threshold=-1.0)


def test_the_sample_script_runs(capsys):
    import pathlib
    import runpy

    runpy.run_path(str(pathlib.Path(__file__).parents[2] / "samples/python/model_and_track.py"))
    out = capsys.readouterr().out
    assert "psd: peak at 50.0 Hz" in out
