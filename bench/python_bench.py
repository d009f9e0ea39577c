#!/usr/bin/env python3
"""Speed of the Python module next to its error: the model on a million points, the tracker on an exactly
shifted texture, Welch on a long signal. Run from the build tree:

    PYTHONPATH=build/release/python /usr/bin/python3 bench/python_bench.py
"""
import math
import time

import numpy as np

import tirstrain


def best_of(repeats, fn):
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        result = fn()
        times.append(time.perf_counter() - start)
    return min(times), result


def model():
    p = dict(normal_N=1.0, tangential_N=0.3, radius_m=0.01, young_Pa=1.0e6, poisson=0.4, friction=1.0)
    rng = np.random.default_rng(0)
    x, y = rng.uniform(-4e-3, 4e-3, (2, 1_000_000))
    seconds, field = best_of(5, lambda: tirstrain.cattaneo_mindlin(x, y, **p))
    # Error: the stick zone's rigid shift (Johnson 1985 §7.2) against its closed form.
    e_star = p["young_Pa"] / (1 - p["poisson"] ** 2)
    a = (3 * p["normal_N"] * p["radius_m"] / (4 * e_star)) ** (1 / 3)
    g = p["young_Pa"] / (2 * (1 + p["poisson"]))
    c = a * 0.7 ** (1 / 3)
    shift = 3 * p["normal_N"] * (2 - p["poisson"]) / (16 * g * a) * (1 - 0.7 ** (2 / 3))
    stick = np.hypot(x, y) < c
    error = np.abs(field["ux_m"][stick] / shift - 1).max()
    print(f"cattaneo_mindlin: {x.size / seconds / 1e6:.1f} M points/s (6 arrays out); "
          f"stick-zone shift max relative error {error:.1e}")


def texture(shape, dx, dy):
    rng = np.random.default_rng(7)
    yy, xx = np.mgrid[0:shape[0], 0:shape[1]].astype(np.float64)
    image = np.zeros(shape)
    for _ in range(24):
        k, angle, phase = 2 * math.pi / rng.uniform(6, 20), rng.uniform(0, 2 * math.pi), rng.uniform(0, 2 * math.pi)
        image += np.cos(k * (math.cos(angle) * (xx - dx) + math.sin(angle) * (yy - dy)) + phase)
    return (0.5 + 0.07 * image).clip(0, 1).astype(np.float32)


def track():
    shifts = [(0.37 * i, -0.21 * i) for i in range(20)]
    frames = [texture((256, 256), dx, dy) for dx, dy in shifts]
    seconds, (reference, position, status) = best_of(3, lambda: tirstrain.track(frames, grid_px=16))
    alive = status[-1] < 10
    error = np.linalg.norm(position[:, alive] - reference[alive] - np.array(shifts)[:, None, :], axis=2)
    print(f"track: {len(frames) / seconds:.0f} frames/s (256x256, {alive.sum()} of {len(reference)} points "
          f"alive); error median {np.median(error):.4f} px, max {error.max():.4f} px")


def psd():
    fs = 10_000.0
    t = np.arange(1_000_000) / fs
    seconds, (freq, density) = best_of(5, lambda: tirstrain.psd(np.sin(2 * math.pi * 123.0 * t),
                                                               sample_rate_Hz=fs, segment=10_000))
    power = density.sum() * (freq[1] - freq[0])
    print(f"psd: {t.size / seconds / 1e6:.1f} M samples/s (segment 10000); peak {freq[np.argmax(density)]:.1f} Hz "
          f"(true 123.0), power relative error {abs(power / 0.5 - 1):.1e}")


if __name__ == "__main__":
    model()
    track()
    psd()
