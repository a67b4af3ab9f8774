"""Kernels of the cluster preparation, the measurement structure and the update of the pairs against their numpy references (moving to tests/oracles)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scenes import Car, Scene
from test_preparation import random_clusters

from tracker import Road, Tracker, TrackerConfig
from tracker import compiled
from tracker.config import MeasurementConfig
from tracker.frame import EgoState
from tracker.measurement import build_structure
from tracker.preparation import _prepare_finite

pytest.importorskip("numba")


def _roads():
    open_road = Road.from_curvature([(200.0, 0.0, 0.0), (300.0, 0.0, 1 / 150.0), (600.0, 1 / 150.0, -1 / 80.0)],
                                    lanes=3, lane_width=3.5)
    th = np.linspace(0.0, 2.0 * np.pi, 13)[:-1]
    ring = Road.from_waypoints(np.column_stack([300.0 * np.cos(th), 200.0 * np.sin(th)]), closed=True, lanes=2,
                               lane_width=3.5)
    return {"clothoid-open": open_road, "hermite-closed": ring}


def assert_fields_equal(a, b, skip=()) -> None:
    """Dataclasses ``a`` (numpy) and ``b`` (compiled): integer and boolean fields equal, float fields
    within 1e-9 with the same non-finite entries, the same shapes and dtypes."""
    for name in a.__dataclass_fields__:
        if name in skip:
            continue
        x, y = np.asarray(getattr(a, name)), np.asarray(getattr(b, name))
        assert x.shape == y.shape and x.dtype == y.dtype, (name, x.shape, y.shape, x.dtype, y.dtype)
        if x.dtype.kind in "bi":
            np.testing.assert_array_equal(x, y, err_msg=name)
        else:
            np.testing.assert_array_equal(np.isfinite(x), np.isfinite(y), err_msg=name)
            fin = np.isfinite(x)
            np.testing.assert_allclose(y[fin], x[fin], rtol=0.0, atol=1e-9, err_msg=name)
            np.testing.assert_array_equal(x[~fin], y[~fin], err_msg=name)


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("config", [MeasurementConfig(), MeasurementConfig(end_gap_correction=False),
                                    MeasurementConfig(max_cluster_points=12)], ids=["default", "no-gap", "12-points"])
def test_compiled_preparation_equals_numpy(seed, config):
    clusters = random_clusters(seed)
    rng = np.random.default_rng(seed)
    velocities = [rng.normal(size=2) if rng.random() < 0.5 else None for _ in clusters]
    ref = _prepare_finite(clusters, velocities, config, compiled=False)
    got = _prepare_finite(clusters, velocities, config, compiled=True)
    valid = ref.valid
    assert_fields_equal(dataclasses.replace(ref, order=np.where(valid, ref.order, 0)),
                        dataclasses.replace(got, order=np.where(got.valid, got.order, 0)), skip=("velocity",))
    assert all((r is None and g is None) or np.array_equal(r, g) for r, g in zip(ref.velocity, got.velocity))
    assert ref.two_sided.any() and (~ref.two_sided).any() and (ref.raw_count > config.max_cluster_points).any()


def _scene_pairs(monkeypatch):
    """The batches, pairs and predicted mean rectangles ``build_structure`` sees in 30 frames of a
    tracker on a 3-lane curve with a truck and radar (recorded from ``tracker.update``)."""
    import tracker.update

    road = Road.from_curvature([(150.0, 0.0, 0.0), (300.0, 0.0, 1 / 120.0)], lanes=3, lane_width=3.5)
    scene = Scene(road, Car(60.0, -3.5, 14.0),
                  [Car(80.0, -3.5, 14.0), Car(75.0, 0.0, 17.0, length=11.0, width=2.5), Car(50.0, 3.5, 18.0),
                   Car(95.0, 0.0, 12.0)], radar=True)
    seen = []

    def record(batch, ci, corners, *args, **kwargs):
        seen.append((batch, np.array(ci), np.array(corners), kwargs.get("extent_sd")))
        return build_structure(batch, ci, corners, *args, **kwargs)

    monkeypatch.setattr(tracker.update, "build_structure", record)
    monkeypatch.setattr(tracker.update, "_update_clusters_fused", lambda *args: None)  # the staged path builds it
    monkeypatch.setattr(tracker.update, "_update_pairs_fused", lambda *args: None)
    tr = Tracker(road, TrackerConfig())
    rng = np.random.default_rng(3)
    for k in range(30):
        tr.step(scene.frame(0.1 * k, rng))
    return seen


@pytest.mark.parametrize("radar_rows", ["speed", "velocity"])
def test_compiled_structure_equals_numpy(radar_rows, monkeypatch):
    config = MeasurementConfig(radar_rows=radar_rows)
    pairs = _scene_pairs(monkeypatch)
    assert len(pairs) >= 20
    assert any(b.occluded_end is not None and b.occluded_end.any() for b, _, _, _ in pairs)  # the scene has shadows
    assert any(b.continued_end is not None for b, _, _, _ in pairs)
    assert all(sd is not None for _, _, _, sd in pairs)
    whole_parts = 0
    for batch, clu, corners, extent_sd in pairs:
        rng = np.random.default_rng(len(clu))
        fused = dataclasses.replace(batch, fused=np.arange(len(batch.fused)) % 2 == 0,
                                    velocity=rng.normal(size=batch.velocity.shape))
        # the recorded shadow / continuation flags and extent sds, random ones (every combination of the
        # two ends; sds that open or shut the gate), and none
        flags = rng.random((len(batch.points), 2)) < 0.4
        for occluded, continued, sd in ((batch.occluded_end, batch.continued_end, extent_sd),
                                        (flags, rng.random(flags.shape) < 0.3, rng.uniform(0.0, 2.0, extent_sd.shape)),
                                        (None, None, None)):
            variant = dataclasses.replace(fused, occluded_end=occluded, continued_end=continued)
            for use_radar in (True, False):
                ref = build_structure(variant, clu, corners, config, use_radar, extent_sd=sd, compiled=False)
                got = build_structure(variant, clu, corners, config, use_radar, extent_sd=sd, compiled=True)
                assert_fields_equal(ref, got)
            if sd is not None:
                off = build_structure(variant, clu, corners, dataclasses.replace(config, sharp_parts_whole=False),
                                      extent_sd=sd, compiled=False)
                whole_parts += int((ref.mode != off.mode).sum())
    assert whole_parts > 0  # the two-sided rule decided some parts


@pytest.mark.parametrize("name", ["clothoid-open", "hermite-closed"])
def test_compiled_to_vehicle_equals_numpy(name, monkeypatch):
    """``to_vehicle`` of curvilinear states, compiled against numpy: any leading shape, 7 and 8 state
    columns, states beyond an open road's ends and across a closed road's seam, extents below
    ``MIN_EXTENT`` and a NaN extent."""
    from tracker.measurement import to_vehicle

    road = _roads()[name]
    rng = np.random.default_rng(2)
    ego = EgoState(120.0, -40.0, 0.7, 12.0, 0.05)
    for shape, dim in (((40,), 7), ((6, 15), 7), ((5, 3, 2), 8), ((0,), 7)):
        x = rng.normal(0.0, 1.0, shape + (dim,))
        x[..., 0] = rng.uniform(-30.0, road.length + 30.0, shape)
        x[..., 1] = rng.uniform(-8.0, 8.0, shape)
        x[..., 3] = rng.uniform(-0.5, 0.5, shape)
        x[..., 5:7] = rng.uniform(-1.0, 15.0, shape + (2,))  # below MIN_EXTENT too
        if road.closed:
            x[..., 0] %= road.length
        if x.size:
            x.reshape(-1, dim)[0, 5] = np.nan  # a NaN extent stays NaN (numpy.maximum's rule)
        monkeypatch.setenv(compiled.ENV_SWITCH, "0")
        ref = to_vehicle(x, ego, road)
        monkeypatch.setenv(compiled.ENV_SWITCH, "1")
        got = to_vehicle(x, ego, road)
        for field in ("center", "psi", "v", "length", "width"):
            a, b = getattr(ref, field), getattr(got, field)
            assert a.shape == b.shape
            np.testing.assert_allclose(b, a, rtol=0.0, atol=1e-9)
            if field in ("v", "length", "width"):
                np.testing.assert_array_equal(b, a)  # copied or floored: exact
        assert got.corners().shape == ref.corners().shape  # the kernel's corners, then numpy's
        np.testing.assert_allclose(got.corners(), ref.corners(), rtol=0.0, atol=1e-9)
        if len(x):
            np.testing.assert_allclose(got.take(np.array([0])).corners(), ref.corners()[[0]], rtol=0.0, atol=1e-9)
    with pytest.raises(ValueError, match="finite"):
        to_vehicle(np.full((2, 7), np.nan), ego, road)


@pytest.mark.parametrize("name", ["clothoid-open", "hermite-closed"])
def test_compiled_sigma_rectangles_equal_the_two_steps(name, monkeypatch):
    """``tracker.update.sigma_rectangles`` (sigma points and their rectangles in one compiled call)
    gives exactly the compiled ``sigma_points`` then ``to_vehicle``, and numpy's within 1e-9; 8-state
    Gaussians across the seam and beyond the ends; a NaN is refused, a covariance that is not positive
    definite goes the numpy way (repaired and counted)."""
    from tracker.measurement import to_vehicle
    from tracker.motion import curvilinear_wrapping
    from tracker.ukf import UnscentedTransform
    from tracker.update import sigma_rectangles

    road = _roads()[name]
    wrapping = curvilinear_wrapping(road)
    ut = UnscentedTransform(n=8)
    rng = np.random.default_rng(5)
    ego = EgoState(120.0, -40.0, 0.7, 12.0, 0.05)
    mean = rng.normal(0.0, 1.0, (25, 8)) * np.r_[1.0, 3.0, 10.0, 0.3, 0.1, 1.0, 0.3, 1.0] + np.r_[0.0, 0, 0, 0, 0, 5.0, 2.0, 0]
    mean[:, 0] = rng.uniform(-20.0, road.length + 20.0, 25)
    if road.closed:
        mean[:, 0] %= road.length
    root = rng.normal(0.0, 1.0, (25, 8, 8)) * rng.uniform(0.02, 1.0, (25, 1, 1))
    cov = root @ np.swapaxes(root, 1, 2) + 1e-3 * np.eye(8)
    monkeypatch.setenv(compiled.ENV_SWITCH, "1")
    sigma, rect = sigma_rectangles(ut, mean, cov, wrapping, ego, road, "curvilinear")
    steps = ut.sigma_points(mean, cov, wrapping)
    ref = to_vehicle(steps, ego, road)
    assert np.array_equal(sigma, steps)
    for field in ("center", "psi", "v", "length", "width"):
        assert np.array_equal(getattr(rect, field), getattr(ref, field))
    assert np.array_equal(rect.corners(), ref.corners())
    monkeypatch.setenv(compiled.ENV_SWITCH, "0")
    sigma0, rect0 = sigma_rectangles(ut, mean, cov, wrapping, ego, road, "curvilinear")
    np.testing.assert_allclose(sigma, sigma0, rtol=0.0, atol=1e-9)
    np.testing.assert_allclose(rect.corners(), rect0.corners(), rtol=0.0, atol=1e-9)
    monkeypatch.setenv(compiled.ENV_SWITCH, "1")
    bad = cov.copy()
    bad[4] = -np.eye(8)
    before = ut.repairs
    sigma_b, _ = sigma_rectangles(ut, mean, bad, wrapping, ego, road, "curvilinear")
    assert ut.repairs > before and np.isfinite(sigma_b).all()
    nan = mean.copy()
    nan[3, 2] = np.nan
    with pytest.raises(ValueError, match="finite"):
        sigma_rectangles(ut, nan, cov, wrapping, ego, road, "curvilinear")


def track_scene(frames: int) -> Tracker:
    """The default tracker run ``frames`` frames (10 Hz, noise seed 0) on a curved three-lane road with
    three cars and an 11 m bus around the ego, with radar."""
    road = Road.from_curvature([(150.0, 0.0, 0.0), (300.0, 0.0, 1 / 120.0)], lanes=3, lane_width=3.5)
    scene = Scene(road, Car(60.0, -3.5, 14.0), [Car(80.0, -3.5, 14.0), Car(75.0, 0.0, 17.0, length=11.0, width=2.5),
                                                 Car(50.0, 3.5, 18.0)], radar=True)
    tracker = Tracker(road, TrackerConfig())
    rng = np.random.default_rng(0)
    for k in range(frames):
        tracker.step(scene.frame(0.1 * k, rng))
    return tracker


def tracked_update_calls(frames: int, monkeypatch) -> list[tuple]:
    """``track_scene(frames)``'s calls of the update (``tracker.update.update_clusters``) as the
    ``update_pairs`` calls they stand for: ``(means, covs, batch, comp, clu, ego, road, config, ut)``,
    the batch prepared by ``prepare_scanned_batch`` as the two-step path prepares it."""
    import tracker.tracker as tt
    from tracker.preparation import prepare_scanned_batch

    raw = []
    original = tt.update_clusters
    monkeypatch.setattr(tt, "update_clusters", lambda *args: raw.append(args) or original(*args))
    track_scene(frames)
    monkeypatch.setattr(tt, "update_clusters", original)
    calls = []
    for means, covs, points, offsets, velocity, has_velocity, comp, clu, scan, ego, road, config, ut in raw:
        used, slot = np.unique(clu, return_inverse=True)
        clusters = [points[offsets[k]:offsets[k + 1]] for k in used]
        velocities = [velocity[k] if has_velocity[k] else None for k in used]
        batch = prepare_scanned_batch(clusters, config.measurement, velocities, scan, config.detection.lidar_resolution,
                                      config.detection.lidar_range)
        calls.append((means, covs, batch, comp, slot, ego, road, config, ut))
    return calls


def _counting(function, taken: list):
    """``function`` that also records in ``taken`` whether each call gave a result (not None)."""
    def counting(*args):
        out = function(*args)
        taken.append(out is not None)
        return out
    return counting


def _lengths_cut(calls: list[tuple]) -> list[tuple]:
    """The update calls ``(means, covs, ...)`` with every prior's length cut to 2 m (sides longer than
    predicted: the fused kernels hand back for the widened prior)."""
    from tracker.motion import LENGTH

    out = []
    for means, covs, *rest in calls:
        short = means.copy()
        short[:, LENGTH] = 2.0
        out.append((short, covs, *rest))
    return out


def _kalman_inputs(rng, pairs, n, rows, extra, wrapping):
    """Random UKF update inputs of a realistic scale: states of road traffic, measurement sigma points
    a smooth nonlinear function of the state, innovations of a few standard deviations."""
    from tracker.ukf import UnscentedTransform

    ut = UnscentedTransform(n=n)
    root = rng.normal(0.0, 1.0, (pairs, n, n)) * rng.uniform(0.05, 1.0, (pairs, 1, 1))
    cov = root @ np.swapaxes(root, 1, 2) + 1e-3 * np.eye(n)
    mean = rng.normal(0.0, 1.0, (pairs, n)) * np.r_[50.0, 3.0, 10.0, 0.3, 0.1, 4.0, 1.0, 1.0][:n]
    mean[: pairs // 3, 3] = np.pi - 0.02  # headings across +-pi
    sigma = ut.sigma_points(mean, cov, wrapping)
    h = rng.normal(0.0, 1.0, (rows, n))
    z_sigma = np.sin(sigma @ h.T / 20.0) * 10.0 + sigma @ h.T
    r = rng.uniform(0.005, 0.3, (pairs, rows))
    mask = rng.random((pairs, rows)) < 0.7
    mask[:, :2] = True
    z = ut.wm @ z_sigma + rng.normal(0.0, 1.0, (pairs, rows)) * np.sqrt(r) * 3.0
    factors = rng.normal(0.0, 0.2, (pairs, extra, rows)) if extra else None
    return ut, sigma, mean, cov, z_sigma, z, r, mask, factors


@pytest.mark.parametrize("extra", [0, 2])
@pytest.mark.parametrize("periodic", [False, True], ids=["open", "closed-road"])
def test_compiled_kalman_update_equals_numpy(extra, periodic, monkeypatch):
    """``tracker.update.kalman_update`` compiled against numpy: padded rows, with and without the
    low-rank noise factors, the heading wrapped across +-pi, ``s`` on a closed road; the 7- and 8-state
    filters; an empty batch."""
    from tracker.ukf import Wrapping
    from tracker.update import kalman_update

    wrapping = Wrapping(angles=(3,), periods=((0, 180.0),) if periodic else ())
    rng = np.random.default_rng(5)
    for n, pairs, rows in ((7, 9, 40), (8, 12, 122), (7, 1, 2), (8, 0, 6)):
        ut, *inputs, factors = _kalman_inputs(rng, pairs, n, rows, extra, wrapping)
        monkeypatch.setenv(compiled.ENV_SWITCH, "0")
        ref = kalman_update(ut, *inputs, wrapping=wrapping, factors=factors)
        monkeypatch.setenv(compiled.ENV_SWITCH, "1")
        got = kalman_update(ut, *inputs, wrapping=wrapping, factors=factors)
        assert ref.nis.size == pairs
        for name in ref.__dataclass_fields__:
            a, b = getattr(ref, name), getattr(got, name)
            if a is None:
                assert b is None
                continue
            assert a.shape == b.shape and a.dtype == b.dtype, name
            np.testing.assert_allclose(b, a, rtol=1e-9, atol=1e-9, err_msg=name)
        assert np.all(np.abs(got.mean[:, 3]) <= np.pi)
        if periodic:
            assert np.all((got.mean[:, 0] >= 0.0) & (got.mean[:, 0] < 180.0))


def test_compiled_kalman_update_of_a_tracked_scene_equals_numpy(monkeypatch):
    """The tracker's own update batches (clusters of three cars and a bus with radar rows): each one
    updated by the kernel and by numpy, both ``kalman_update`` alone (its inputs from a numpy run) and
    ``update_pairs`` whole (whose compiled path predicts the measurements, gates the radar rows and
    updates in one call, ``tracker.kalman.measurement_update_kernel``)."""
    import tracker.update as tu

    kalman_batches = []
    original, original_pairs = tu.kalman_update, tu.update_pairs

    def keep(*args, **kwargs):
        kalman_batches.append((args, kwargs))
        return original(*args, **kwargs)

    monkeypatch.setattr(tu, "kalman_update", keep)
    monkeypatch.setenv(compiled.ENV_SWITCH, "0")
    pair_batches = [(args, {}) for args in tracked_update_calls(12, monkeypatch)]
    monkeypatch.setenv(compiled.ENV_SWITCH, "1")
    assert sum(b[0][4].shape[0] for b in kalman_batches) >= 20
    for args, kwargs in kalman_batches:
        monkeypatch.setenv(compiled.ENV_SWITCH, "0")
        ref = original(*args, **kwargs)
        monkeypatch.setenv(compiled.ENV_SWITCH, "1")
        got = original(*args, **kwargs)
        for name in ("mean", "cov", "log_likelihood", "nis", "dim", "predicted", "innovation"):
            np.testing.assert_allclose(getattr(got, name), getattr(ref, name), rtol=1e-9, atol=1e-9, err_msg=name)
    fused = 0
    for args, kwargs in pair_batches:
        monkeypatch.setenv(compiled.ENV_SWITCH, "0")
        ref = original_pairs(*args, **kwargs)
        monkeypatch.setenv(compiled.ENV_SWITCH, "1")
        got = original_pairs(*args, **kwargs)
        fused += int(np.asarray(args[2].fused).sum())
        assert np.array_equal(got.radar_rejected, ref.radar_rejected) and np.array_equal(got.dim, ref.dim)
        for name in ("mean", "cov", "log_likelihood", "nis", "predicted", "innovation"):
            np.testing.assert_allclose(getattr(got, name), getattr(ref, name), rtol=1e-9, atol=1e-9, err_msg=name)
    assert fused >= 20  # clusters with a radar velocity took part


@pytest.mark.parametrize("dim", [7, 8])
def test_compiled_extent_rules_equal_numpy(dim, monkeypatch):
    """``tracker.update.apply_extent_rules`` by ``tracker.extent`` and by numpy on random pairs
    built to reach every rule: lengths and widths held or seen whole, trucks' widths with a car's length
    (the long-vehicle prior), measured narrow widths (the narrow one), estimates beyond the largest
    vehicle, the sensor ahead of and behind the rectangles; the same numbers, bit for bit, with the
    rules on and off."""
    from tracker.config import BirthConfig
    from tracker.measurement import FROM_A, FULL, Structure
    from tracker.update import UpdateResult, apply_extent_rules

    rng = np.random.default_rng(7)
    pairs = 400
    prior = np.zeros((pairs, dim))
    prior[:, 0], prior[:, 1], prior[:, 2] = rng.uniform(0, 200, pairs), rng.uniform(-5, 5, pairs), rng.uniform(0, 30, pairs)
    prior[:, 3] = rng.normal(0.0, 0.5, pairs)
    prior[:, 5] = rng.choice([2.0, 4.5, 13.0, 30.0], pairs) + rng.normal(0.0, 0.3, pairs)
    prior[:, 6] = rng.choice([0.8, 1.8, 2.5, 3.4], pairs) + rng.normal(0.0, 0.05, pairs)
    root = rng.normal(0.0, 1.0, (pairs, dim, dim)) * rng.uniform(0.02, 0.6, (pairs, 1, 1))
    prior_cov = root @ np.swapaxes(root, 1, 2) + 1e-3 * np.eye(dim)
    post = prior + rng.normal(0.0, 0.3, (pairs, dim))
    post_cov = prior_cov * rng.uniform(0.5, 1.0, (pairs, 1, 1))
    mode = rng.choice([FULL, FROM_A], (pairs, 2))
    sides = rng.integers(0, 4, (pairs, 2))
    centre = rng.normal(0.0, 30.0, (pairs, 1, 2))
    corners = centre + rng.normal(0.0, 2.0, (pairs, 4, 2))
    structure = Structure(*([None] * 7), two_sided=None, sides=sides, mode=mode, radar=None, z=None, r=None,
                          mask=None, factors=None, excess=None)
    for birth, hold in ((BirthConfig(), True), (BirthConfig(), False),
                        (BirthConfig(long_width=None, narrow_width=None, max_length=None, max_width=None), True),
                        (BirthConfig(narrow_width_std=0.6, length_std=0.2), True)):
        config = TrackerConfig(birth=birth, measurement=MeasurementConfig(hold_unobserved_extent=hold))
        out = {}
        for flag in ("0", "1"):
            monkeypatch.setenv(compiled.ENV_SWITCH, flag)
            res = UpdateResult(post.copy(), post_cov.copy(), *([None] * 5))
            out[flag] = apply_extent_rules(res, prior, prior_cov, structure, corners, config)
        assert np.array_equal(out["0"].mean, out["1"].mean) and np.array_equal(out["0"].cov, out["1"].cov)
        changed = ~np.isclose(out["1"].mean[:, 5], post[:, 5])
        assert changed.sum() >= 20  # the rules did something


@pytest.mark.parametrize("settled", [None, 0.15])
def test_compiled_grow_extent_equals_numpy(settled, monkeypatch):
    """``tracker.update.grow_extent`` by ``tracker.extent.grow_extent_kernel`` and by numpy:
    random excesses (some not finite) on long and short parts, narrow and wide extent spreads, the
    sensor on either side; the same mask and covariances, bit for bit, and both extents grown somewhere."""
    from tracker.measurement import Structure
    from tracker.update import grow_extent

    rng = np.random.default_rng(11)
    pairs, dim = 300, 8
    means = rng.normal(0.0, 1.0, (pairs, dim)) * np.r_[50.0, 3.0, 10.0, 0.5, 0.1, 3.0, 0.5, 1.0]
    root = rng.normal(0.0, 1.0, (pairs, dim, dim)) * rng.uniform(0.02, 0.8, (pairs, 1, 1))
    covs = root @ np.swapaxes(root, 1, 2) + 1e-4 * np.eye(dim)
    excess = rng.normal(0.0, 2.0, (pairs, 2))
    excess[rng.random((pairs, 2)) < 0.1] = np.nan
    excess[rng.random((pairs, 2)) < 0.05] = np.inf
    sides = rng.integers(0, 4, (pairs, 2))
    corners = rng.normal(0.0, 30.0, (pairs, 1, 2)) + rng.normal(0.0, 2.0, (pairs, 4, 2))
    structure = Structure(*([None] * 7), two_sided=None, sides=sides, mode=None, radar=None, z=None, r=None,
                          mask=None, factors=None, excess=excess)
    out = {}
    for flag in ("0", "1"):
        monkeypatch.setenv(compiled.ENV_SWITCH, flag)
        out[flag] = grow_extent(means, covs, structure, corners, settled)
    assert np.array_equal(out["0"][0], out["1"][0]) and np.array_equal(out["0"][1], out["1"][1])
    grown = out["1"][0]
    for index in (5, 6):
        assert (grown & (out["1"][1][:, index, index] > covs[:, index, index])).sum() >= 10


def test_the_fused_update_of_the_pairs_equals_the_staged_kernels(monkeypatch):
    """``tracker.update.update_pairs`` by one compiled call (``tracker.pairs``) gives the staged
    kernels' numbers bit for bit: every call of a tracked scene (a bus, radar, shadows) replayed both
    ways, and the same calls with the priors' lengths cut to 2 m (sides longer than predicted: the
    kernel hands the pairs back for the widened prior, and the staged path runs)."""
    import tracker.update as tu

    calls = tracked_update_calls(15, monkeypatch)
    assert len(calls) >= 14
    taken = []
    counting = _counting(tu._update_pairs_fused, taken)
    for case in calls + _lengths_cut(calls):
        monkeypatch.setattr(tu, "_update_pairs_fused", counting)
        got = tu.update_pairs(*case)
        monkeypatch.setattr(tu, "_update_pairs_fused", lambda *args: None)
        ref = tu.update_pairs(*case)
        for name in ("mean", "cov", "log_likelihood", "nis", "dim", "predicted", "innovation", "radar_rejected"):
            np.testing.assert_array_equal(getattr(got, name), getattr(ref, name), err_msg=name)
    assert all(taken[: len(calls)])  # the scene's own calls: all by the fused kernel
    assert not all(taken[len(calls):])  # some shortened priors grew: handed back to the staged path


def test_the_fused_preparation_and_update_equal_the_two_steps(monkeypatch):
    """``tracker.update.update_clusters`` by one compiled call (``tracker.pairs.prepared_pairs_kernel``:
    the clusters prepared with their shadow flags, then the fused update) gives bit for bit what
    ``prepare_scanned_batch`` then ``update_pairs`` give, and the same counts of shadowed and continued
    ends: every call of a tracked scene (a bus, radar, ends in shadows), and the same calls with the priors'
    lengths cut to 2 m (the kernel hands back; the two steps run)."""
    import tracker.tracker as tt
    import tracker.update as tu

    raw = []
    original = tt.update_clusters
    monkeypatch.setattr(tt, "update_clusters", lambda *args: raw.append(args) or original(*args))
    road = Road.from_curvature([(150.0, 0.0, 0.0), (300.0, 0.0, 1 / 120.0)], lanes=3, lane_width=3.5)
    scene = Scene(road, Car(60.0, -3.5, 14.0),
                  [Car(80.0, -3.5, 14.0), Car(75.0, 0.0, 17.0, length=11.0, width=2.5), Car(50.0, 3.5, 18.0),
                   Car(95.0, 0.0, 12.0)], radar=True)  # the structure test's scene: shadows, a bus, radar
    tracker, rng = Tracker(road, TrackerConfig()), np.random.default_rng(3)
    for k in range(30):
        tracker.step(scene.frame(0.1 * k, rng))
    monkeypatch.setattr(tt, "update_clusters", original)
    assert len(raw) >= 28
    taken = []
    counting = _counting(tu._update_clusters_fused, taken)
    counts = []
    for case in raw + _lengths_cut(raw):
        monkeypatch.setattr(tu, "_update_clusters_fused", counting)
        got, occluded, continued = tu.update_clusters(*case)
        monkeypatch.setattr(tu, "_update_clusters_fused", lambda *args: None)
        ref, ref_occluded, ref_continued = tu.update_clusters(*case)
        assert (occluded, continued) == (ref_occluded, ref_continued)
        counts.append(occluded)
        for name in ("mean", "cov", "log_likelihood", "nis", "dim", "predicted", "innovation", "radar_rejected"):
            np.testing.assert_array_equal(getattr(got, name), getattr(ref, name), err_msg=name)
    assert sum(taken[: len(raw)]) >= 0.8 * len(raw)  # the scene's own calls: by the one kernel (a bus's side may grow)
    assert not all(taken[len(raw):])  # some shortened priors grew: handed back to the two steps
    assert any(c for c in counts), counts  # some ends in a shadow
    # a non-finite point in a cluster of some pair: the kernel hands back, the two steps take it
    means, covs, points, offsets, velocity, has_velocity, comp, clu, *rest = raw[-1]
    bad = points.copy()
    bad[offsets[clu[0]]] = np.nan
    assert tu._update_clusters_fused(means, covs, bad, offsets, velocity, has_velocity, comp, clu, *rest) is None
    # ... and in a cluster of no pair: the kernel still runs (only the pairs' clusters are prepared)
    idle = np.setdiff1d(np.arange(len(offsets) - 1), clu)
    if len(idle) and offsets[idle[0] + 1] > offsets[idle[0]]:
        bad = points.copy()
        bad[offsets[idle[0]]] = np.nan
        got = tu._update_clusters_fused(means, covs, bad, offsets, velocity, has_velocity, comp, clu, *rest)
        ref = tu._update_clusters_fused(means, covs, points, offsets, velocity, has_velocity, comp, clu, *rest)
        np.testing.assert_array_equal(got[0].mean, ref[0].mean)
    with pytest.raises(ValueError, match="does not exist"):
        tu.update_clusters(means, covs, points, offsets, velocity, has_velocity, comp, clu + len(offsets), *rest)
    with pytest.raises(ValueError, match="offsets must rise"):
        tu.update_clusters(means, covs, points, offsets[::-1], velocity, has_velocity, comp, clu, *rest)
    # a non-finite radar velocity: the fused call declines, the two steps raise their error
    bad_velocity = velocity.copy()
    bad_velocity[clu[0]] = np.nan
    has = has_velocity.copy()
    has[clu[0]] = True
    with pytest.raises(ValueError, match="finite"):
        tu.update_clusters(means, covs, points, offsets, bad_velocity, has, comp, clu, *rest)


def test_a_non_finite_prior_takes_the_staged_update_and_its_error(monkeypatch):
    """A NaN in a prior: the fused update hands the pairs back and the staged path's error is raised,
    as before the fusion."""
    import tracker.update as tu

    calls = tracked_update_calls(4, monkeypatch)
    means, covs, *rest = calls[-1]
    bad = means.copy()
    bad[0, 2] = np.nan
    with pytest.raises(ValueError, match="finite"):
        tu.update_pairs(bad, covs, *rest)


def test_the_papers_euler_conversion_never_takes_the_fused_update(monkeypatch):
    """The ``paper`` variant converts states to E by the paper's Euler integration
    (``MeasurementConfig.conversion = "euler"``), which the fused kernels do not do: its tracker gives the
    same numbers with the fused calls as with the two steps, and the fused calls decline its updates."""
    import tracker.tracker as tt
    import tracker.update as tu
    from sim.evaluation.variants import variant_config

    config = variant_config("paper")
    assert config.measurement.conversion == "euler"
    road = Road.from_curvature([(80.0, 0.0, 0.0), (200.0, 0.0, 1 / 90.0)], lanes=3, lane_width=3.5)
    scene = Scene(road, Car(40.0, -3.5, 14.0), [Car(60.0, -3.5, 14.0), Car(55.0, 0.0, 17.0), Car(70.0, 3.5, 12.0)])

    def run() -> list:
        tracker, rng = Tracker(road, config), np.random.default_rng(2)
        return [(t.label, t.mean.copy()) for k in range(12) for t in tracker.step(scene.frame(0.1 * k, rng))]

    calls = []
    original = tt.update_clusters
    monkeypatch.setattr(tt, "update_clusters", lambda *args: calls.append(args) or original(*args))
    fused = run()
    monkeypatch.setattr(tt, "update_clusters", original)
    assert calls and all(tu._update_clusters_fused(*args) is None for args in calls)
    monkeypatch.setattr(tu, "_update_clusters_fused", lambda *args: None)
    monkeypatch.setattr(tu, "_update_pairs_fused", lambda *args: None)
    staged = run()
    assert len(fused) == len(staged) > 0
    for (label, mean), (ref_label, ref_mean) in zip(fused, staged):
        assert label == ref_label
        np.testing.assert_array_equal(mean, ref_mean)
