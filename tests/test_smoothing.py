"""sim.world.smoothing: the RTS smoother recovers a known vehicle path from noisy samples, reads a
standing car's sideways drift as noise, and bounds car widths."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim.world.recording import RecordedVehicle, Recording
from sim.world.smoothing import SmootherConfig, smooth_recording, smooth_vehicle

DT = 0.1


def _ctra_path(steps: int = 100):
    """A car accelerating into a curve: heading rate ramps to 0.1 rad/s, acceleration +1.5 m/s^2 then -2."""
    t = DT * np.arange(steps)
    a = np.where(t < 4.0, 1.5, -2.0)
    v = 12.0 + np.concatenate([[0.0], np.cumsum(a[:-1]) * DT])
    w = np.clip(0.05 * t, 0.0, 0.1)
    yaw = np.concatenate([[0.0], np.cumsum(w[:-1]) * DT])
    xy = np.zeros((steps, 2))
    for k in range(1, steps):
        xy[k] = xy[k - 1] + v[k - 1] * DT * np.array([math.cos(yaw[k - 1]), math.sin(yaw[k - 1])])
    return t, xy, yaw, v, w


def test_smoother_recovers_the_path_from_noise():
    t, xy, yaw, v, w = _ctra_path()
    rng = np.random.default_rng(7)
    noisy_xy = xy + rng.normal(0.0, 0.3, xy.shape)
    noisy_yaw = yaw + rng.normal(0.0, math.radians(2.0), yaw.shape)
    noisy_v = np.abs(np.hypot(*np.gradient(noisy_xy, DT, axis=0).T))  # speeds from the noisy centres, as NGSIM's
    raw = RecordedVehicle(1, t, noisy_xy, noisy_yaw, noisy_v, 4.5, 1.8)
    out = smooth_vehicle(raw)
    inner = slice(5, -5)  # away from the ends, where a smoother has one side only
    pos_raw = np.sqrt(np.mean(np.sum((noisy_xy - xy) ** 2, axis=1)[inner]))
    pos_out = np.sqrt(np.mean(np.sum((out.xy - xy) ** 2, axis=1)[inner]))
    assert pos_out < 0.5 * pos_raw
    assert np.sqrt(np.mean((out.yaw - yaw)[inner] ** 2)) < math.radians(1.0)
    assert np.sqrt(np.mean((out.v - v)[inner] ** 2)) < 0.4
    assert np.abs(np.diff(out.v) / DT).max() < 4.0 < np.abs(np.diff(noisy_v) / DT).max()
    rate_raw = np.sqrt(np.mean((raw.yaw_rate - w)[inner] ** 2))  # differences of the noisy headings
    assert np.sqrt(np.mean((out.yaw_rate - w)[inner] ** 2)) < min(0.05, 0.2 * rate_raw)


def test_standing_car_drift_is_noise():
    """A stopped car whose recorded centre wanders across its heading by +-0.4 m (video tracking; 1.26
    m/s at its fastest) barely moves sideways once smoothed."""
    t = DT * np.arange(40)
    xy = np.column_stack([np.zeros_like(t), 0.4 * np.sin(math.pi * t)])  # across its heading (yaw 0)
    raw = RecordedVehicle(1, t, xy, np.zeros_like(t), np.full_like(t, 0.5), 4.5, 1.8)
    out = smooth_vehicle(raw)
    d = np.diff(out.xy, axis=0) / DT
    sideways = np.abs(-np.sin(out.yaw[:-1]) * d[:, 0] + np.cos(out.yaw[:-1]) * d[:, 1])
    assert sideways.max() < 0.3
    assert np.abs(np.degrees(out.yaw)).max() < 3.0


def test_widths_and_report():
    t = DT * np.arange(5)
    wide = RecordedVehicle(1, t, np.column_stack([10 * t, 0 * t]), 0 * t, np.full(5, 10.0), 4.6, 2.59)
    truck = RecordedVehicle(2, t, np.column_stack([10 * t, 4 + 0 * t]), 0 * t, np.full(5, 10.0), 12.0, 2.59)
    single = RecordedVehicle(3, [0.0], [[0.0, 8.0]], [0.0], [0.0], 4.0, 2.3)
    rec, report = smooth_recording(Recording("r", (wide, truck, single)))
    assert [v.width for v in rec] == [2.1, 2.59, 2.1]
    assert report.widths_bounded == 2 and report.vehicles == 3
    assert rec.vehicle(3).xy.tolist() == [[0.0, 8.0]]
    assert smooth_vehicle(wide, SmootherConfig(max_car_width=None)).width == 2.59
    with pytest.raises(ValueError, match="SmootherConfig.position_std must be a positive number"):
        SmootherConfig(position_std=0.0)
