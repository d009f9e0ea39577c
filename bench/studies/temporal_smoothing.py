#!/usr/bin/env python3
"""How much would adaptive smoothing of each track in time lower the displacement error?

An offline study of what `process` does itself on noisy trials (flow/temporal_smoothing.hpp, docs/flow.md
"After the trial"), which differs in two points: there the sample itself is the shortest window, and σ is
the smaller of the 2nd- and 3rd-difference estimates. Each frame-0 track's
position series is smoothed by local polynomial fits whose window is chosen per frame by the intersection
of confidence intervals (left-sided, right-sided and centred windows of 1..32 frames, fused by inverse
variance; the noise level from the series' own second differences). Scored against the exact field.

Usage: temporal_smoothing.py RESULT.h5 TRUTH.h5 [GAMMA=1.5] [ORDER=1]
  RESULT.h5, TRUTH.h5: `tirstrain validate --scene S --out V` writes V/result/result.h5, V/trial/truth.h5.
Needs python3-h5py and python3-scipy (Debian). Takes ~3 min per 60-frame trial.
"""
import sys

import h5py
import numpy as np
from scipy.interpolate import RegularGridInterpolator
from scipy.signal import savgol_filter

WINDOWS = (1, 2, 3, 4, 6, 8, 12, 16, 24, 32)  # half-lengths, frames


def track_errors(result, truth, tracks):
    """measured − exact displacement [N, len(tracks), 2] in px (frame-0 tracks: reference = frame 0)."""
    pos = result['/tracks/position_px'][...]
    ref = result['/tracks/reference_px'][...]
    gx, gy = truth['/grid/x_px'][...], truth['/grid/y_px'][...]
    field = truth['/field/displacement_px'][...]
    err = np.full((pos.shape[0], len(tracks), 2), np.nan)
    at = np.stack([ref[tracks, 1], ref[tracks, 0]], 1)
    for f in range(pos.shape[0]):
        for c in range(2):
            exact = RegularGridInterpolator((gy, gx), field[f, :, :, c], method='cubic')(at)
            err[f, :, c] = pos[f, tracks, c] - ref[tracks, c] - exact
    return err


def local_fit(t, x, t0, idx, order):
    """value at t0 of the least-squares polynomial through (t[idx], x[idx]), and its variance factor."""
    a = np.vander(t[idx] - t0, order + 1)
    p = np.linalg.pinv(a)
    return p[-1] @ x[idx], np.sum(p[-1] ** 2)


def smooth(t, x, sigma, gamma, order):
    out = x.copy()
    n = len(x)
    for i in range(n):
        estimates = []
        for side in ('centred', 'left', 'right'):
            low, high, best = -np.inf, np.inf, None
            for h in WINDOWS:
                a = i - h if side != 'right' else i
                b = i + h if side != 'left' else i
                if a < 0 or b > n - 1:
                    break
                idx = np.arange(a, b + 1)
                if len(idx) < order + 2:
                    continue
                value, factor = local_fit(t, x, t[i], idx, order)
                sd = sigma * np.sqrt(factor)
                low, high = max(low, value - gamma * sd), min(high, value + gamma * sd)
                if low > high:  # this window disagrees with the shorter ones: motion the fit cannot follow
                    break
                best = (value, sd * sd)
            if best:
                estimates.append(best)
        if estimates:
            w = np.array([1.0 / v for _, v in estimates])
            out[i] = np.sum(w * np.array([v for v, _ in estimates])) / np.sum(w)
    return out


def rms(e):
    alive = np.isfinite(e[..., 0])
    return np.sqrt(np.mean(np.sum(e[alive] ** 2, -1)))


def main():
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    gamma = float(sys.argv[3]) if len(sys.argv) > 3 else 1.5
    order = int(sys.argv[4]) if len(sys.argv) > 4 else 1
    result, truth = h5py.File(sys.argv[1], 'r'), h5py.File(sys.argv[2], 'r')
    pos = result['/tracks/position_px'][...]
    t = result['/frames/t_s'][...]
    tracks = np.where(result['/tracks/born_frame'][...] == 0)[0]
    err = track_errors(result, truth, tracks)
    smoothed = err.copy()
    for k, track in enumerate(tracks):
        alive = np.where(np.isfinite(pos[:, track, 0]))[0]
        for run in np.split(alive, np.where(np.diff(alive) != 1)[0] + 1):
            if len(run) < 5:
                continue
            for c in range(2):
                x = pos[run, track, c]
                d2 = x[2:] - 2 * x[1:-1] + x[:-2]
                sigma = 1.4826 * np.median(np.abs(d2 - np.median(d2))) / np.sqrt(6)
                if sigma > 0:
                    smoothed[run, k, c] = err[run, k, c] + smooth(t[run], x, sigma, gamma, order) - x
    alive_once = np.isfinite(err[1:, :, 0]).any(axis=0)
    per_track_mean = np.nanmean(err[1:, alive_once], axis=0)
    print(f'{len(tracks)} frame-0 tracks, frames 1..{len(t) - 1}')
    print(f'displacement RMS px: measured {rms(err[1:]):.4f}, smoothed in time {rms(smoothed[1:]):.4f} '
          f'(gamma {gamma}, order {order})')
    print(f'  of which constant per track (anchor noise, ridge-phase bias): {rms(per_track_mean[None]):.4f}')
    # How much is averageable at all: the error's own whiteness, and the error series smoothed alone.
    fluct = err[1:, alive_once] - per_track_mean[None]
    a, b = fluct[1:], fluct[:-1]
    both = np.isfinite(a[..., 0]) & np.isfinite(b[..., 0])
    lag1 = [np.corrcoef(a[both][:, c], b[both][:, c])[0, 1] for c in range(2)]
    print(f'  lag-1 correlation of the error about its track mean: x {lag1[0]:.2f}, y {lag1[1]:.2f}')
    for w in (5, 15):
        alone = err.copy()
        for k in range(len(tracks)):
            alive = np.where(np.isfinite(err[:, k, 0]))[0]
            for run in np.split(alive, np.where(np.diff(alive) != 1)[0] + 1):
                if len(run) >= w:
                    alone[run, k] = savgol_filter(err[run, k], w, 2, axis=0, mode='interp')
        print(f'  the error series alone smoothed over {w} frames (the motion known exactly): {rms(alone[1:]):.4f}')
    print('frame: measured -> smoothed')
    for f in range(1, len(t), 6):
        print(f'  {f:3d}: {rms(err[f:f + 1]):.3f} -> {rms(smoothed[f:f + 1]):.3f}')


if __name__ == '__main__':
    main()
