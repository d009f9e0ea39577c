#!/usr/bin/env python3
"""tirstrain from Python: the Cattaneo-Mindlin field on a grid, a texture tracked through a known shift,
and the spectrum of a force-like signal.

Run from the build tree:  PYTHONPATH=build/release/python /usr/bin/python3 samples/python/model_and_track.py
"""
import math

import numpy as np

import tirstrain

# 1. The surface field of a 1 N normal, 0.3 N tangential load on a 10 mm fingertip (E = 1 MPa, nu = 0.4).
x, y = np.meshgrid(np.linspace(-3e-3, 3e-3, 61), np.linspace(-3e-3, 3e-3, 61))
field = tirstrain.cattaneo_mindlin(x, y, normal_N=1.0, tangential_N=0.3, radius_m=0.01, young_Pa=1.0e6,
                                   poisson=0.4, friction=1.0)
centre = field["ux_m"][30, 30]
print(f"model: stick-zone shift {centre * 1e6:.2f} um, largest |Exx| {np.abs(field['Exx']).max():.4f}, "
      f"largest energy density {field['energy_density_J_m3'].max():.1f} J/m^3")

# 2. A smooth random texture moved by (0.7, -0.3) px per frame, tracked on a 16 px grid.
rng = np.random.default_rng(0)
waves = [(2 * math.pi / rng.uniform(6, 20), rng.uniform(0, 2 * math.pi), rng.uniform(0, 2 * math.pi))
         for _ in range(24)]
gy, gx = np.mgrid[0:96, 0:128].astype(float)


def frame(dx, dy):
    image = sum(np.cos(k * (math.cos(a) * (gx - dx) + math.sin(a) * (gy - dy)) + p) for k, a, p in waves)
    return (0.5 + 0.07 * image).clip(0, 1).astype(np.float32)


frames = [frame(0.7 * i, -0.3 * i) for i in range(4)]
reference, position, status = tirstrain.track(frames, grid_px=16)
alive = (status[-1] >= 0) & (status[-1] < 10)  # -1: retired in an earlier frame
shift = np.median(position[-1][alive] - reference[alive], axis=0)
print(f"track: {len(reference)} points, {alive.sum()} alive; last frame's median shift "
      f"({shift[0]:.3f}, {shift[1]:.3f}) px, true (2.100, -0.900) px")

# 3. The Welch spectrum of a 50 Hz vibration sampled at 1 kHz.
t = np.arange(4000) / 1000.0
freq, psd = tirstrain.psd(np.sin(2 * math.pi * 50 * t) + 0.1 * rng.standard_normal(t.size),
                          sample_rate_Hz=1000.0, segment=500)
print(f"psd: peak at {freq[np.argmax(psd)]:.1f} Hz")
