"""Tests of tracker/compiled: every numba kernel against its numpy reference (the same discrete
decisions exactly, the numbers within 1e-9), on random clusters and on the pairs of a tracked scene; and
the switch (``EOT_NUMBA``). numba is a dependency of the package; the tests skip where it cannot be
imported."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scenes import Car, Scene
from test_preparation import random_clusters

from tracker import Road, Tracker, TrackerConfig
from tracker import compiled
from tracker.config import MeasurementConfig, MotionConfig
from tracker.frame import EgoState
from tracker.measurement import build_structure
from tracker.motion import FrenetMotion
from tracker.preparation import _prepare_finite, prepare_batch

pytest.importorskip("numba")


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


def test_switch(monkeypatch):
    monkeypatch.setenv(compiled.ENV_SWITCH, "0")
    assert not compiled.enabled()
    monkeypatch.setenv(compiled.ENV_SWITCH, "1")
    assert compiled.enabled() == compiled.available()


def test_pinned_switch_is_read_once_per_block(monkeypatch):
    """``compiled.pinned()`` (one ``Tracker.step``): the switch as it was when the outermost block
    began, whatever the environment says inside; read again after the block (also after an error)."""
    monkeypatch.setenv(compiled.ENV_SWITCH, "0")
    with compiled.pinned() as on:
        assert on is False
        monkeypatch.setenv(compiled.ENV_SWITCH, "1")
        assert not compiled.enabled()
        with compiled.pinned():
            assert not compiled.enabled()
        assert not compiled.enabled()  # the inner block left the outer one's value
    assert compiled.enabled() == compiled.available()
    with pytest.raises(RuntimeError):
        with compiled.pinned():
            monkeypatch.setenv(compiled.ENV_SWITCH, "0")
            raise RuntimeError("a failed frame")
    assert not compiled.enabled()


def _roads():
    open_road = Road.from_curvature([(200.0, 0.0, 0.0), (300.0, 0.0, 1 / 150.0), (600.0, 1 / 150.0, -1 / 80.0)],
                                    lanes=3, lane_width=3.5)
    th = np.linspace(0.0, 2.0 * np.pi, 13)[:-1]
    ring = Road.from_waypoints(np.column_stack([300.0 * np.cos(th), 200.0 * np.sin(th)]), closed=True, lanes=2,
                               lane_width=3.5)
    return {"clothoid-open": open_road, "hermite-closed": ring}


@pytest.mark.parametrize("name", ["clothoid-open", "hermite-closed"])
def test_compiled_centerline_frame_equals_numpy(name, monkeypatch):
    curve = _roads()[name]._curve
    s = np.concatenate([np.random.default_rng(0).uniform(0.0, curve.length, 3000), [0.0, curve.length],
                        curve.starts[:-1], np.nextafter(curve.starts[1:], 0.0)])
    monkeypatch.setenv(compiled.ENV_SWITCH, "0")
    ref = curve.frame(s)
    monkeypatch.setenv(compiled.ENV_SWITCH, "1")
    got = curve.frame(s)
    for a, b in zip(ref, got):
        assert a.shape == b.shape
        np.testing.assert_allclose(b, a, rtol=0.0, atol=1e-9)


@pytest.mark.parametrize("name", ["clothoid-open", "hermite-closed"])
def test_compiled_projection_equals_numpy(name, monkeypatch):
    """``Road.to_frenet``'s Newton iterations compiled against numpy: points on and off the road,
    beyond an open road's ends (extrapolated), across a closed road's seam, near a centre of
    curvature (the fallback), with and without hints (good and bad ones)."""
    road = _roads()[name]
    rng = np.random.default_rng(1)
    s = np.concatenate([rng.uniform(0.0, road.length, 2000), [0.0, road.length, 1e-9, road.length - 1e-9]])
    n = rng.uniform(road.right_edge - 30.0, road.left_edge + 30.0, s.size)
    xy = road.to_cartesian(s, n)
    if not road.closed:  # beyond both ends, along and beside the end tangents
        x0, y0, c0, s0 = road._ends[0]
        x1, y1, c1, s1 = road._ends[1]
        xy = np.concatenate([xy, [[x0 - 25.0 * c0, y0 - 25.0 * s0], [x1 + 40.0 * c1 - 3.0 * s1, y1 + 40.0 * s1 + 3.0 * c1]]])
        s = np.concatenate([s, [0.0, road.length]])
    hints = [None, s + rng.normal(0.0, 2.0, s.size), (s + 0.5 * road.length) % road.length]  # good, then bad hints
    for hint in hints:
        monkeypatch.setenv(compiled.ENV_SWITCH, "0")
        ref = road.to_frenet(xy, s_hint=hint)
        monkeypatch.setenv(compiled.ENV_SWITCH, "1")
        got = road.to_frenet(xy, s_hint=hint)
        ds = got[0] - ref[0]
        if road.closed:  # s just below the length and just above 0 are the same place
            ds = (ds + 0.5 * road.length) % road.length - 0.5 * road.length
        np.testing.assert_allclose(ds, 0.0, rtol=0.0, atol=1e-9)
        np.testing.assert_allclose(got[1], ref[1], rtol=0.0, atol=1e-9)


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
def test_the_report_centres_equal_to_vehicle_compiled_exactly(name, monkeypatch):
    """``Tracker._extract``'s report-range centres (``tracker.tracker._centres``: one compiled call,
    ``report_centres_kernel``) are ``to_vehicle(means[index]).center``'s compiled numbers bit for bit,
    and numpy's with the kernels off: 7 and 8 columns, beyond an open road's ends, a repeated index, one
    row, none, a non-C-contiguous mixture; a non-finite ``s`` among the rows raises to_vehicle's error."""
    from tracker.measurement import to_vehicle
    from tracker.tracker import _centres

    road = _roads()[name]
    rng = np.random.default_rng(7)
    ego = EgoState(120.0, -40.0, 0.7, 12.0, 0.05)
    for dim in (7, 8):
        means = rng.normal(0.0, 1.0, (30, dim))
        means[:, 0] = rng.uniform(-30.0, road.length + 30.0, 30) % (road.length if road.closed else np.inf)
        means[:, 1] = rng.uniform(-8.0, 8.0, 30)
        means[3, 0] = np.nan  # not among the rows asked for: no error
        for index in (np.array([0, 5, 5, 29, 2]), np.array([11]), np.arange(4, 30), np.zeros(0, dtype=np.intp)):
            index = index.astype(np.intp)
            for switch in ("1", "0"):
                monkeypatch.setenv(compiled.ENV_SWITCH, switch)
                with compiled.pinned():
                    got = _centres(means, index, ego, road, "curvilinear")
                    ref = to_vehicle(means[index], ego, road).center
                assert got.shape == ref.shape == (len(index), 2)
                assert np.array_equal(got, ref)
        monkeypatch.setenv(compiled.ENV_SWITCH, "1")
        strided = np.asfortranarray(means)
        assert np.array_equal(_centres(strided, np.array([1, 2], dtype=np.intp), ego, road, "curvilinear"),
                              to_vehicle(means[[1, 2]], ego, road).center)
        with pytest.raises(ValueError, match="s must be finite"):
            _centres(means, np.array([1, 3], dtype=np.intp), ego, road, "curvilinear")


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


@pytest.mark.parametrize("name", ["clothoid-open", "hermite-closed"])
@pytest.mark.parametrize("motion", [MotionConfig(), MotionConfig(acceleration=True), MotionConfig(slip_lever=0.0)],
                         ids=["default", "acceleration", "no-slip"])
def test_compiled_frenet_propagation_equals_numpy(name, motion, monkeypatch):
    """States on and beyond the road (open ends extrapolate straight), backwards and standing, over
    one frame and over several RK4 sub-steps."""
    road = _roads()[name]
    model = FrenetMotion(road, motion)
    rng = np.random.default_rng(1)
    count = 240
    cols = [rng.uniform(-30.0, road.length + 30.0, count), rng.uniform(-6.0, 6.0, count),
            rng.uniform(-3.0, 35.0, count), rng.normal(0.0, 0.4, count), rng.normal(0.0, 0.3, count),
            rng.uniform(3.0, 16.0, count), rng.uniform(1.5, 2.6, count)]
    if model.dim == 8:
        cols.append(rng.normal(0.0, 2.0, count))
    x = np.column_stack(cols).reshape(16, 15, -1)
    for dt in (0.1, 1.0 / 14.0, 1.3):
        monkeypatch.setenv(compiled.ENV_SWITCH, "0")
        ref = model.propagate(x, dt)
        monkeypatch.setenv(compiled.ENV_SWITCH, "1")
        got = model.propagate(x, dt)
        assert got.shape == ref.shape
        np.testing.assert_allclose(got, ref, rtol=0.0, atol=1e-9)


@pytest.mark.parametrize("seed", range(3))
def test_compiled_detection_model_equals_numpy(seed, monkeypatch):
    """``detection_model`` compiled against numpy: rectangles all around the sensor (across the +-pi
    seam behind it), near and beyond the lidar range, hidden by nearer tracks of other labels and by
    scan returns; without occluders, without a scan, with occlusion off, and for no components."""
    from tracker.config import DetectionConfig
    from tracker.detection import detection_model, occluded_fraction
    from tracker.measurement import Rectangles

    rng = np.random.default_rng(seed)

    def rects(count):
        r, b = rng.uniform(3.0, 110.0, count), rng.uniform(-np.pi, np.pi, count)
        b[:3] = np.pi - rng.uniform(0.0, 0.02, 3)  # straddling the seam behind the sensor
        return Rectangles(np.column_stack([r * np.cos(b), r * np.sin(b)]), rng.uniform(-np.pi, np.pi, count),
                          rng.uniform(0.0, 30.0, count), rng.uniform(2.0, 14.0, count), rng.uniform(1.5, 2.6, count))

    comps, tracks = rects(60), rects(12)
    labels = rng.integers(0, 15, 60)
    track_labels = rng.integers(0, 15, 12)
    scan = np.concatenate([tracks.corners().reshape(-1, 2), rng.uniform(-60.0, 60.0, (400, 2))])
    scan = np.concatenate([scan, scan[:200] * rng.uniform(0.97, 1.03, (200, 1))])  # several beams on one ray
    cases = [(DetectionConfig(), tracks, track_labels, scan), (DetectionConfig(), None, None, scan),
             (DetectionConfig(), tracks, track_labels, None), (DetectionConfig(occlusion=False), tracks, track_labels, scan),
             (DetectionConfig(), tracks.take(np.arange(0)), track_labels[:0], scan[:0])]
    results = []
    for config, occ, occ_labels, sc in cases:
        monkeypatch.setenv(compiled.ENV_SWITCH, "0")
        ref = detection_model(comps, labels, config, occ, occ_labels, scan=sc)
        monkeypatch.setenv(compiled.ENV_SWITCH, "1")
        got = detection_model(comps, labels, config, occ, occ_labels, scan=sc)
        for a, b in zip(ref, got):
            np.testing.assert_allclose(b, a, rtol=1e-12, atol=1e-12)
        results.append(ref)
    for flag in ("0", "1"):  # occluded_fraction on its own (the births' test)
        monkeypatch.setenv(compiled.ENV_SWITCH, flag)
        results.append(occluded_fraction(comps, labels, tracks, track_labels))
    np.testing.assert_allclose(results[-1], results[-2], rtol=1e-12, atol=1e-12)
    assert (results[-1] > 0.0).any()
    p_d = results[0][1]  # occlusion lowers some P_D part-way, range cuts others to 0
    assert ((p_d > 0.0) & (p_d < DetectionConfig().p_detection)).any() and (p_d == 0.0).any()
    monkeypatch.setenv(compiled.ENV_SWITCH, "1")
    empty = detection_model(comps.take(np.arange(0)), labels[:0], DetectionConfig(), tracks, track_labels, scan=scan)
    assert empty[0].shape == (0,) and empty[1].shape == (0,)


def test_compiled_curvature_interpolation_equals_numpy_interp():
    """The RK4 kernel's table lookup (the interval from ``s / step``, corrected at knots) gives
    ``numpy.interp``'s numbers exactly: random ``s``, every knot and its neighbouring floats."""
    from tracker.compiled.motion import _interp

    xp = np.linspace(0.0, 1234.567, 4939)
    fp = np.random.default_rng(0).normal(size=xp.size)
    knots = xp[::7]
    x = np.concatenate([np.random.default_rng(1).uniform(0.0, xp[-1], 3000), knots, np.nextafter(knots, -1.0),
                        np.nextafter(knots, 2000.0)])
    x = x[(x >= 0.0) & (x <= xp[-1])]
    assert np.array_equal(np.array([_interp(v, xp, fp) for v in x]), np.interp(x, xp, fp))


@pytest.mark.parametrize("name", ["clothoid-open", "hermite-closed"])
@pytest.mark.parametrize("motion", [MotionConfig(), MotionConfig(acceleration=True)], ids=["default", "acceleration"])
def test_compiled_ukf_prediction_equals_numpy(name, motion, monkeypatch):
    """``tracker.motion.predict`` with the compiled kernels (one fused call) against numpy: headings
    near +-pi (wrapped sigma points), ``s`` near a closed road's seam, wide and narrow covariances,
    per-state jerks, the acceleration relaxed and floored first (``relax``, ``floor``: the same as
    predicting the relaxed Gaussians); the fused call gives exactly the numbers of the compiled steps
    one by one; a NaN
    is refused; a covariance that is not positive definite takes the numpy path, which repairs and
    counts it."""
    from tracker.motion import predict, relax_acceleration
    from tracker.ukf import UnscentedTransform

    road = _roads()[name]
    model = FrenetMotion(road, motion)
    ut = UnscentedTransform(n=model.dim)
    rng = np.random.default_rng(3)
    count = 30
    cols = [rng.uniform(0.0, road.length, count), rng.uniform(-6.0, 6.0, count), rng.uniform(0.0, 30.0, count),
            rng.normal(0.0, 0.3, count), rng.normal(0.0, 0.2, count), rng.uniform(3.0, 16.0, count),
            rng.uniform(1.5, 2.6, count)]
    if model.dim == 8:
        cols.append(rng.normal(0.0, 1.0, count))
    mean = np.column_stack(cols)
    mean[:5, 3] = np.pi - 0.01  # sigma points across +-pi
    mean[5:10, 0] = [0.0, 0.05, road.length - 0.05, 1e-9, road.length - 1e-9]  # across the seam or the open ends
    root = rng.normal(0.0, 1.0, (count, model.dim, model.dim)) * rng.uniform(0.01, 2.0, (count, 1, 1))
    cov = root @ np.swapaxes(root, 1, 2) + 1e-3 * np.eye(model.dim)
    jerks = (None, rng.uniform(0.5, 3.0, count)) if model.dim == 8 else (None,)
    for dt in (0.1, 1.0 / 14.0):
        for jerk in jerks:
            monkeypatch.setenv(compiled.ENV_SWITCH, "0")
            ref_pts = ut.sigma_points(mean, cov, model.wrapping)
            ref = predict(ut, model, mean, cov, dt, jerk)
            monkeypatch.setenv(compiled.ENV_SWITCH, "1")
            np.testing.assert_allclose(ut.sigma_points(mean, cov, model.wrapping), ref_pts, rtol=0.0, atol=1e-12)
            got = predict(ut, model, mean, cov, dt, jerk)  # one fused call (FrenetMotion.predict_compiled)
            for a, b in zip(ref, got):
                assert a.shape == b.shape
                np.testing.assert_allclose(b, a, rtol=1e-10, atol=1e-10)
            with monkeypatch.context() as m:  # the compiled steps one by one: the very same numbers
                m.setattr(FrenetMotion, "predict_compiled", None)
                steps = predict(ut, model, mean, cov, dt, jerk)
            assert all(np.array_equal(a, b) for a, b in zip(steps, got))
            if model.dim == 8:  # the tracker's coasting relaxation and a manoeuvre onset's floor, first
                relax = np.where(rng.random(count) < 0.5, rng.uniform(0.5, 1.0, count), 1.0)
                floor = np.where(rng.random(count) < 0.3, rng.uniform(0.0, 3.0, count), -np.inf)
                got = predict(ut, model, mean, cov, dt, jerk, relax, floor)
                with monkeypatch.context() as m:
                    m.setattr(FrenetMotion, "predict_compiled", None)
                    steps = predict(ut, model, mean, cov, dt, jerk, relax, floor)
                assert all(np.array_equal(a, b) for a, b in zip(steps, got))
                m2, p2 = relax_acceleration(mean, cov, relax, floor)
                assert not np.array_equal(m2, mean) and np.array_equal(m2[relax == 1.0], mean[relax == 1.0])
                assert all(np.array_equal(a, b) for a, b in zip(predict(ut, model, m2, p2, dt, jerk), got))
    nan = mean.copy()
    nan[2, 1] = np.nan
    with pytest.raises(ValueError, match="must be finite"):
        predict(ut, model, nan, cov, 0.1)
    bad = cov.copy()
    bad[3] = -np.eye(model.dim)  # not positive definite
    before = ut.repairs
    got = predict(ut, model, mean, bad, 0.1)
    assert ut.repairs > before and np.isfinite(got[1]).all()


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
    updates in one call, ``tracker.compiled.kalman.measurement_update_kernel``)."""
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
    """``tracker.update.apply_extent_rules`` by ``tracker.compiled.extent`` and by numpy on random pairs
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
    """``tracker.update.grow_extent`` by ``tracker.compiled.extent.grow_extent_kernel`` and by numpy:
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


@pytest.mark.parametrize("bin_deg", [0.2, 0.37])
def test_compiled_bearing_filter_equals_numpy(bin_deg, monkeypatch):
    """``tracker.preprocess.bearing_filter`` by ``bearing_filter_kernel`` and by numpy: a scan of rays
    on the bins' centres, points sharing a bin at equal ranges (the first index wins), points across
    +-pi (one bin when the bins tile the circle, 0.2 deg; not for 0.37 deg); the same indices."""
    from tracker.preprocess import bearing_filter

    rng = np.random.default_rng(13)
    width = np.deg2rad(bin_deg)
    rays = np.arange(-np.pi, np.pi, width)
    ranges = rng.uniform(2.0, 90.0, len(rays))
    pts = [np.column_stack([ranges * np.cos(rays), ranges * np.sin(rays)])]
    pts.append(rng.normal(0.0, 30.0, (500, 2)))
    twin = pts[0][::7] * 1.0  # the same points again: equal ranges in one bin
    pts.append(twin)
    pts.append(np.array([[-10.0, 1e-12], [-10.0, -1e-12], [-12.0, 0.0]]))  # across +-pi
    pts = np.concatenate(pts)
    rng.shuffle(pts)
    out = {}
    for flag in ("0", "1"):
        monkeypatch.setenv(compiled.ENV_SWITCH, flag)
        out[flag] = bearing_filter(pts, width)
    assert np.array_equal(out["0"], out["1"]) and len(out["1"]) >= len(rays) // 2


@pytest.mark.parametrize("name", ["clothoid-open", "hermite-closed"])
def test_compiled_projection_seed_equals_numpy(name, monkeypatch):
    """``Road.to_frenet`` without a hint seeds its Newton iterations by ``seed_kernel`` when the
    kernels are on: on the seed grid exactly numpy's seed (``Road._nearest_node`` then ``Road._seed``),
    off it (points far from the road) left to the k-d tree; ``(s, n)`` within 1e-9 of numpy's for
    points on the road, far off it, and mixed."""
    from tracker.compiled.centerline import seed_kernel
    from tracker.road import PROJECTION_MIN_DENOMINATOR, SEED_GRID_RESOLUTION

    road = _roads()[name]
    rng = np.random.default_rng(17)
    near = road.to_cartesian(rng.uniform(0.0, road.length, 400), rng.uniform(-10.0, 10.0, 400))
    far = near + rng.normal(0.0, 200.0, (400, 2))
    pts = np.ascontiguousarray(np.concatenate([near, far]))
    got, missing = seed_kernel(pts, road._grid_origin, 1.0 / SEED_GRID_RESOLUTION, road._grid, road._node_frame,
                               road._nodes, PROJECTION_MIN_DENOMINATOR)
    assert missing.any() and (~missing).any()
    assert np.array_equal(got[~missing], road._seed(pts, road._nearest_node(pts))[~missing])
    for xy in (near, far, pts):
        out = {}
        for flag in ("1", "0"):
            monkeypatch.setenv(compiled.ENV_SWITCH, flag)
            out[flag] = road.to_frenet(xy)
        for a, b in zip(out["0"], out["1"]):
            np.testing.assert_allclose(b, a, rtol=0.0, atol=1e-9)


@pytest.mark.parametrize("seed", range(4))
def test_compiled_distance_partition_equals_numpy(seed, monkeypatch):
    """Scattered points, a dense random walk (cells holding many points), points exactly on the
    grid's cell boundaries, a few points spread over kilometres (more grid columns than the counting
    sort takes: the cells sorted by argsort) and points too far apart for the grid's keys; thresholds
    from 0.2 to 3 m."""
    from tracker.clustering import distance_partition

    rng = np.random.default_rng(seed)
    clouds = [rng.uniform(-80.0, 80.0, (600, 2)), np.cumsum(rng.normal(0.0, 0.4, (700, 2)), axis=0),
              np.round(rng.uniform(-5.0, 5.0, (300, 2)) / 0.25) * 0.25, rng.uniform(-1.0, 1.0, (1, 2)),
              np.concatenate([rng.uniform(-2000.0, 2000.0, (40, 2)), rng.uniform(0.0, 3.0, (20, 2))]),
              np.array([[0.0, 0.0], [1e18, -1e18], [0.5, 0.0]])]  # keys that would overflow: the numpy path
    for pts in clouds:
        for threshold in (0.2, 0.5 * np.sqrt(2.0), 1.0, 3.0):
            monkeypatch.setenv(compiled.ENV_SWITCH, "0")
            ref = distance_partition(pts, threshold)
            monkeypatch.setenv(compiled.ENV_SWITCH, "1")
            np.testing.assert_array_equal(distance_partition(pts, threshold), ref)


@pytest.mark.parametrize("seed", range(3))
def test_compiled_occluded_ends_equal_numpy(seed, monkeypatch):
    """The bearing ends of clusters of 1-40 points scattered around the sensor (some behind it, across
    the bearing seam, some near the range limit) in a scan of their own points and a few hundred others; windows of 1-5
    rays, and the range cut on and off: the same flags, and some of each."""
    from tracker.clustering import occluded_ends

    rng = np.random.default_rng(seed)
    flags = []
    for _ in range(60):
        clusters = []
        for _ in range(int(rng.integers(1, 12))):
            r, b = rng.uniform(5.0, 100.0), rng.uniform(-np.pi, np.pi)
            centre = r * np.array([np.cos(b), np.sin(b)])
            clusters.append(centre + rng.normal(0.0, 1.0, (int(rng.integers(1, 40)), 2)))
        scan = np.concatenate(clusters + [rng.uniform(-100.0, 100.0, (int(rng.integers(0, 400)), 2))])
        ends = prepare_batch(clusters).bearing_ends()
        for window in np.radians([0.2, 0.5, 1.0]):
            for max_range, range_margin in ((np.inf, 0.0), (100.0, 5.0)):
                monkeypatch.setenv(compiled.ENV_SWITCH, "0")
                ref = occluded_ends(ends, scan, window, 0.5, max_range, range_margin)
                monkeypatch.setenv(compiled.ENV_SWITCH, "1")
                got = occluded_ends(ends, scan, window, 0.5, max_range, range_margin)
                np.testing.assert_array_equal(got, ref)
                flags.append(ref)
    flags = np.concatenate(flags)
    assert flags.any() and (~flags).any() and (flags[:, 0] != flags[:, 1]).any()


@pytest.mark.parametrize("seed", range(3))
def test_compiled_radar_association_equals_numpy(seed, monkeypatch):
    """Clusters (some empty) and detections scattered so that gates overlap and many pairs compete."""
    from tracker.clustering import associate_radar

    rng = np.random.default_rng(seed)
    for _ in range(100):
        clusters = [rng.normal(rng.uniform(-20.0, 20.0, 2), 1.0, (int(rng.integers(0, 30)), 2))
                    for _ in range(int(rng.integers(1, 12)))]
        radar = rng.uniform(-20.0, 20.0, (int(rng.integers(0, 15)), 2))
        monkeypatch.setenv(compiled.ENV_SWITCH, "0")
        ref = associate_radar(clusters, radar, 3.0)
        monkeypatch.setenv(compiled.ENV_SWITCH, "1")
        got = associate_radar(clusters, radar, 3.0)
        assert got.dtype == ref.dtype
        np.testing.assert_array_equal(got, ref)


@pytest.mark.parametrize("seed", range(3))
def test_compiled_merge_equals_numpy(seed, monkeypatch):
    """Mixtures of clumps of components (so that groups form), headings across +-pi and arc lengths
    across a closed road's seam, with and without wrapping."""
    from tracker.reduction import Mixture, merge
    from tracker.ukf import Wrapping

    rng = np.random.default_rng(seed)
    wrappings = [Wrapping(), Wrapping(angles=(3,), periods=((0, 500.0),))]
    for _ in range(60):
        n = int(rng.integers(2, 40))
        centre = rng.choice([0.5, 250.0, 499.6], size=n)
        means = np.column_stack([centre + rng.normal(0, 1.0, n), rng.normal(0, 1.0, n), rng.uniform(5, 30, n),
                                 rng.choice([-3.1, 0.0, 3.1], size=n) + rng.normal(0, 0.05, n), rng.normal(0, 0.1, n),
                                 rng.uniform(3, 12, n), rng.uniform(1.5, 2.6, n)])
        a = rng.normal(size=(n, 7, 7)) * rng.uniform(0.1, 1.0, (n, 1, 1))
        covs = a @ np.swapaxes(a, 1, 2) + 0.05 * np.eye(7)
        mix = Mixture(rng.uniform(0.01, 1.0, n), np.mod(means, [500.0, 1e9, 1e9, 1e9, 1e9, 1e9, 1e9]), covs,
                      rng.integers(0, 50, n))
        for wrapping in wrappings:
            for gate in (4.0, 30.0):
                monkeypatch.setenv(compiled.ENV_SWITCH, "0")
                ref = merge(mix, gate, wrapping)
                monkeypatch.setenv(compiled.ENV_SWITCH, "1")
                got = merge(mix, gate, wrapping)
                np.testing.assert_array_equal(got.labels, ref.labels)
                for name in ("weights", "means", "covs"):
                    np.testing.assert_allclose(getattr(got, name), getattr(ref, name), rtol=1e-9, atol=1e-9)


@pytest.mark.parametrize("seed", range(3))
def test_compiled_points_in_rectangles_and_overlap_groups_equal_numpy(seed, monkeypatch):
    """Overlapping and disjoint rectangles of every heading (duplicate hypotheses of one vehicle, trucks
    beside cars), points inside, between and outside them, and on the widened rectangles' corners."""
    from tracker.clustering import points_in_rectangles
    from tracker.measurement import Rectangles
    from tracker.tracker import _duplicate_groups

    rng = np.random.default_rng(seed)
    for _ in range(60):
        t = int(rng.integers(1, 16))
        centre = rng.uniform(-15.0, 15.0, (t, 2))
        rect = Rectangles(centre, rng.uniform(-np.pi, np.pi, t), np.zeros(t), rng.uniform(2.0, 14.0, t),
                          rng.uniform(0.8, 2.6, t))
        # the widened rectangles' corners lie on their circumscribed circles, where the kernel's
        # distance test (skip a rectangle beyond that circle) is at its boundary
        from tracker.measurement import rectangle_corners

        corners = rectangle_corners(centre, rect.psi, rect.length + 1.4, rect.width + 1.4).reshape(-1, 2)
        pts = np.concatenate([rng.uniform(-20.0, 20.0, (300, 2)), centre + rng.normal(0.0, 1.0, (t, 2)), corners])
        results = {}
        for mode in ("0", "1"):
            monkeypatch.setenv(compiled.ENV_SWITCH, mode)
            results[mode] = (points_in_rectangles(pts, rect.center, rect.psi, rect.length, rect.width, 0.7),
                             _duplicate_groups(rect))
        for ref, got in zip(results["0"], results["1"]):
            np.testing.assert_array_equal(got, ref)
        assert results["0"][1].max() < t or t == 1


def test_warm_up_compiles_every_kernel_once_per_process():
    """After warm_up() every kernel the tracker calls from Python has a compiled signature (those called
    only inside other kernels compile with them), the staged update's too (where the fused one hands
    back), and a tracked scene adds none (no compilation inside a timed frame); a second warm_up()
    returns at once."""
    import tracker.compiled.centerline as kc
    import tracker.compiled.clustering as kl
    import tracker.compiled.motion as km
    import tracker.compiled.preparation as kp
    import tracker.compiled.reduction as kr
    import tracker.compiled.structure as ks
    import tracker.compiled.detection as kd
    import tracker.compiled.kalman as kk
    import tracker.compiled.extent as ke
    import tracker.compiled.pairs as kq
    import tracker.compiled.preprocess as kf
    import tracker.compiled.gating as kg
    import tracker.compiled.birth as kb
    import tracker.compiled.ukf as ku
    import tracker.compiled.extraction as kx

    assert compiled.warm_up()
    kernels = [kp.prepare_kernel, ks.structure_kernel, kc.curve_frame, kc.project_kernel, km.ukf_predict_kernel,
               kl.partition_points_kernel, kl.cluster_points_kernel, kl.ordered_clusters_kernel,
               kl.cluster_radar_kernel, kl.points_in_rectangles_kernel,
               kl.overlap_groups_kernel, kr.reduce_kernel, kc.rectangles_kernel, kc.sigma_rectangles_kernel,
               kd.detection_kernel, kd.occluded_kernel, kl.occluded_ends_kernel, kk.measurement_update_kernel,
               ke.grow_extent_kernel, ke.extent_rules_kernel, kq.update_pairs_kernel, kp.scanned_batch_kernel,
               kr.overlapping_pairs_kernel, kf.road_filter_kernel, kc.seed_kernel, kg.candidate_pairs_kernel, kq.prepared_pairs_kernel,
               kb.road_births_kernel, ku.certainly_positive_definite, kr.inside_updated_kernel,
               kr.absorb_candidates_kernel, kr.overlapping_candidates_kernel, kx.report_centres_kernel]
    before = [len(k.signatures) for k in kernels]
    assert all(n >= 1 for n in before)
    track_scene(15)
    assert [len(k.signatures) for k in kernels] == before
    assert compiled.warm_up()


def test_the_fused_update_of_the_pairs_equals_the_staged_kernels(monkeypatch):
    """``tracker.update.update_pairs`` by one compiled call (``tracker.compiled.pairs``) gives the staged
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
    """``tracker.update.update_clusters`` by one compiled call (``tracker.compiled.pairs.prepared_pairs_kernel``:
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

@pytest.mark.parametrize("seed", range(3))
def test_compiled_overlap_test_of_absorb_overlapping_equals_numpy(seed, monkeypatch):
    """``tracker.reduction.absorb_overlapping`` with its overlap test compiled
    (``tracker.compiled.reduction.overlapping_pairs_kernel``) and by numpy: random heavy components of
    a few labels, apart and overlapping, curvilinear (across a closed road's seam too) and Cartesian;
    the same mixtures and counts, and both outcomes (absorbed, none) reached."""
    from tracker.reduction import Mixture, absorb_overlapping
    from tracker.ukf import Wrapping

    rng = np.random.default_rng(seed)
    outcomes = set()
    for _ in range(80):
        n = int(rng.integers(2, 14))
        means = np.column_stack([rng.choice([1.0, 150.0, 499.0], n) + rng.normal(0.0, 6.0, n), rng.normal(0.0, 2.0, n),
                                 rng.uniform(5, 30, n), rng.normal(0.0, 0.3, n), np.zeros(n),
                                 rng.uniform(3.0, 14.0, n), rng.uniform(1.6, 2.6, n)])
        covs = np.broadcast_to(np.diag([1.0, 0.1, 1.0, 0.01, 0.01, rng.uniform(0.1, 2.0), 0.05]), (n, 7, 7)).copy()
        mix = Mixture(rng.uniform(0.3, 1.0, n), np.mod(means, [500.0, *[1e9] * 6]), covs, rng.integers(1, 6, n))
        for wrapping, cartesian in ((Wrapping(angles=(3,)), False), (Wrapping(angles=(3,), periods=((0, 500.0),)), False),
                                    (Wrapping(angles=(3,)), True)):
            args = (mix, 0.5, 0.3, wrapping, cartesian, {1, 2}, {2, 3})
            monkeypatch.setenv(compiled.ENV_SWITCH, "0")
            ref, ref_count = absorb_overlapping(*args)
            monkeypatch.setenv(compiled.ENV_SWITCH, "1")
            got, count = absorb_overlapping(*args)
            assert count == ref_count
            for name in ("weights", "means", "covs", "labels"):
                np.testing.assert_array_equal(getattr(got, name), getattr(ref, name))
            outcomes.add(count > 0)
    assert outcomes == {True, False}


def test_overlapping_pairs_kernel_against_the_rule():
    """``overlapping_pairs_kernel`` against the rule written out here: ``i`` and ``j`` overlap when the
    centres are closer along the road (along ``i``'s heading, Cartesian) than half the lengths' sum
    less ``overlap``, and across it than half the narrower width; ``s`` wraps on a closed road."""
    from tracker.compiled.reduction import overlapping_pairs_kernel

    rng = np.random.default_rng(7)
    hits = 0
    for cartesian, period in ((False, 0.0), (False, 300.0), (True, 0.0)):
        for _ in range(30):
            n = int(rng.integers(2, 12))
            m = np.column_stack([rng.choice([2.0, 150.0, 298.0], n) + rng.normal(0.0, 5.0, n), rng.normal(0.0, 2.0, n),
                                 np.zeros(n), rng.normal(0.0, 0.4, n), np.zeros(n), rng.uniform(3.0, 14.0, n),
                                 rng.uniform(1.6, 2.6, n)])
            heading = m[:, 3] if cartesian else np.zeros(n)
            got = overlapping_pairs_kernel(m, np.cos(heading), np.sin(heading), cartesian, 0.3, period)
            for i in range(n):
                for j in range(n):
                    d = m[j, :2] - m[i, :2]
                    if period:
                        d[0] -= period * np.floor(d[0] / period + 0.5)
                    c, s = np.cos(heading[i]), np.sin(heading[i])
                    along, across = (d[0] * c + d[1] * s, -d[0] * s + d[1] * c) if cartesian else (d[0], d[1])
                    rule = (i != j and abs(along) < 0.5 * (m[i, 5] + m[j, 5]) - 0.3
                            and abs(across) < 0.5 * min(m[i, 6], m[j, 6]))
                    assert got[i, j] == rule, (cartesian, period, i, j)
                    hits += rule
    assert hits > 0


@pytest.mark.parametrize("dim", [1, 2, 3])
def test_compiled_merge_of_low_dimensional_mixtures_equals_numpy(dim, monkeypatch):
    """Merging states of one to three coordinates (the position bound reads the first two only where
    they exist): the same groups and moments as numpy."""
    from tracker.reduction import Mixture, merge

    rng = np.random.default_rng(dim)
    for _ in range(50):
        n = int(rng.integers(2, 12))
        root = rng.normal(0.0, 1.0, (n, dim, dim)) * rng.uniform(0.2, 1.5, (n, 1, 1))
        mix = Mixture(rng.uniform(0.05, 1.0, n), rng.choice([0.0, 3.0, 40.0], (n, 1)) + rng.normal(0.0, 1.0, (n, dim)),
                      root @ np.swapaxes(root, 1, 2) + 0.05 * np.eye(dim), rng.integers(0, 9, n))
        monkeypatch.setenv(compiled.ENV_SWITCH, "0")
        ref = merge(mix, 4.0)
        monkeypatch.setenv(compiled.ENV_SWITCH, "1")
        got = merge(mix, 4.0)
        np.testing.assert_array_equal(got.labels, ref.labels)
        for name in ("weights", "means", "covs"):
            np.testing.assert_allclose(getattr(got, name), getattr(ref, name), rtol=1e-9, atol=1e-9)


def test_compiled_merge_at_the_gate_equals_numpy(monkeypatch):
    """Pairs whose distance lies just inside and just outside the gate along one axis of a diagonal
    covariance (where the position bound that lets the kernel skip a pair equals the distance itself):
    the same groups as numpy's merge; a covariance with a zero variance is never skipped by the bound."""
    from tracker.reduction import Mixture, merge

    gate = 4.0
    for axis in (0, 1):
        for factor in (1.0 - 1e-7, 1.0 + 1e-7, 1.0 + 1e-5, 1.0 - 1e-5):
            covs = np.broadcast_to(np.diag([2.0, 0.5, 1.0, 0.01, 0.01, 0.3, 0.05]), (2, 7, 7)).copy()
            means = np.zeros((2, 7))
            means[1, axis] = np.sqrt(gate * covs[0, axis, axis] * factor)
            mix = Mixture(np.array([0.9, 0.6]), means, covs, np.array([1, 2]))
            monkeypatch.setenv(compiled.ENV_SWITCH, "0")
            ref = merge(mix, gate)
            monkeypatch.setenv(compiled.ENV_SWITCH, "1")
            got = merge(mix, gate)
            assert len(got) == len(ref) == (1 if factor < 1.0 else 2), (axis, factor)
            np.testing.assert_array_equal(got.labels, ref.labels)


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


@pytest.mark.parametrize("seed", range(3))
def test_compiled_continued_ends_equal_numpy(seed, monkeypatch):
    """``continued_ends`` compiled (the scan sorted by bearing, each end searching the bearing window of
    the disc its test can reach) against numpy: ends all around the sensor (across the seam behind it,
    and within a few metres of it, where the disc holds the lidar), returns scattered and returns placed
    on the ends' continuations; the same flags, and some of each."""
    from tracker.clustering import continued_ends

    rng = np.random.default_rng(seed)
    flags = []
    for _ in range(40):
        k = int(rng.integers(1, 12))
        r = np.concatenate([rng.uniform(0.5, 4.0, 2), rng.uniform(4.0, 90.0, 2 * k - 2)])
        b = rng.uniform(-np.pi, np.pi, 2 * k)
        b[:2] = np.pi - rng.uniform(0.0, 0.01, 2)
        ends = np.column_stack([r * np.cos(b), r * np.sin(b)]).reshape(k, 2, 2)
        angle = rng.uniform(-np.pi, np.pi, (k, 2))
        outward = np.stack([np.cos(angle), np.sin(angle)], axis=-1)
        half_gap = rng.uniform(0.05, 1.0, (k, 2))
        on_line = ends + outward * rng.uniform(0.0, 3.0, (k, 2, 1)) + rng.normal(0.0, 0.2, (k, 2, 2))
        scan = np.concatenate([rng.uniform(-90.0, 90.0, (300, 2)), on_line.reshape(-1, 2)])
        monkeypatch.setenv(compiled.ENV_SWITCH, "0")
        ref = continued_ends(ends, outward, half_gap, scan, 2.0, 0.3)
        monkeypatch.setenv(compiled.ENV_SWITCH, "1")
        got = continued_ends(ends, outward, half_gap, scan, 2.0, 0.3)
        np.testing.assert_array_equal(got, ref)
        flags.append(ref)
    flags = np.concatenate([f.ravel() for f in flags])
    assert flags.any() and not flags.all()


def _random_mixture(rng, n: int, dim: int, road_length: float):
    """``n`` random components of ``dim`` (7 or 8) state entries in a few groups of near-duplicates
    (merged by a gate of 4), some across a closed road's start (``s`` below 0 and at or beyond
    ``road_length``), weights partly at 1e-4 (the prune threshold) and 0.5, labels of a few values."""
    centre = rng.choice([-0.4, 0.0, 30.0, road_length - 0.3, road_length, 0.5 * road_length], n)
    means = np.column_stack([centre + rng.choice([0.0, 1.0], n) * rng.normal(0.0, 0.8, n), rng.normal(0.0, 1.5, n),
                             rng.uniform(5, 30, n), rng.normal(0.0, 0.2, n) + rng.choice([0.0, np.pi], n),
                             rng.normal(0.0, 0.05, n), rng.uniform(3.0, 14.0, n), rng.uniform(1.6, 2.6, n),
                             rng.normal(0.0, 0.5, n)])[:, :dim]
    root = rng.normal(0.0, 0.3, (n, dim, dim))
    covs = root @ np.swapaxes(root, 1, 2) + np.diag(rng.uniform(0.05, 2.0, dim))
    weights = np.where(rng.random(n) < 0.2, rng.choice([1e-4, np.nextafter(1e-4, 0.0), 0.5], n), rng.uniform(0.0, 1.0, n))
    return weights, means, covs, rng.integers(1, 5, n)


def _staged_reduce_in_view(mix, near, limit, lateral, bounds, period, **settings):
    """The reduce stage as ``Tracker._reduce`` ran it before ``reduce_in_view``: the mask of the
    components in view and on the road, ``Mixture.take``, ``reduce`` (its compiled merge when the
    kernels are on) and ``numpy.mod`` of ``s``."""
    from tracker.reduction import reduce

    inside = near <= limit
    on_road = (lateral >= bounds[0]) & (lateral <= bounds[1])
    counts = int((~inside).sum()), int((inside & ~on_road).sum())
    mix = reduce(mix.take(inside & on_road), **settings)
    if period is not None and len(mix):
        mix.means[:, 0] = np.mod(mix.means[:, 0], period)
    return mix, counts


@pytest.mark.parametrize("dim", [7, 8])
@pytest.mark.parametrize("seed", range(2))
def test_compiled_reduce_in_view_equals_the_staged_reduction(seed, dim, monkeypatch):
    """``tracker.reduction.reduce_in_view`` by one compiled call (``reduce_kernel``) against the staged
    compiled path it replaces, bit for bit (weights, means, covariances, labels, both counts): random
    mixtures of 0 to 25 components, 7 and 8 state entries, closed (``s`` wraps, before and after the
    merge) and open roads, ranges and lateral offsets at their limits, weights at the prune threshold,
    heavy components of one label left apart (``merge_same_label``'s frames), caps of 3 and 100; and the
    numpy path against it (the same labels and counts, numbers to rounding)."""
    from tracker.reduction import Mixture, reduce_in_view
    from tracker.ukf import Wrapping

    rng = np.random.default_rng(seed)
    length, limit, bounds = 400.0, 60.0, (-3.0, 2.5)
    seen = {"pending": 0, "capped": 0, "merged": 0, "empty": 0}
    for trial in range(120):
        n = int(rng.integers(0, 26)) if trial % 10 else int(trial % 3)  # some empty and single mixtures
        mix = Mixture(*_random_mixture(rng, n, dim, length))
        near = np.where(rng.random(n) < 0.15, limit, rng.uniform(0.0, 1.3 * limit, n))
        lateral = np.where(rng.random(n) < 0.15, rng.choice(bounds, n), mix.means[:, 1] if n else np.zeros(0))
        closed = bool(trial % 2)
        wrapping = Wrapping(angles=(3,), periods=((0, length),) if closed else ())
        settings = dict(prune_threshold=1e-4, merge_gate=4.0, max_components=3 if trial % 4 == 0 else 100,
                        wrapping=wrapping, same_label_distance=None if trial % 5 == 0 else 3.0,
                        same_label_min_weight=0.5, same_label_along_length=bool(trial % 3))
        period = length if closed else None
        monkeypatch.setenv(compiled.ENV_SWITCH, "1")
        ref, ref_counts = _staged_reduce_in_view(mix, near, limit, lateral, bounds, period, **settings)
        got, *counts = reduce_in_view(mix, near, limit, lateral, bounds, s_period=period, **settings)
        assert tuple(counts) == ref_counts
        for name in ("weights", "means", "covs", "labels"):
            a, b = getattr(got, name), getattr(ref, name)
            assert a.shape == b.shape and a.dtype == b.dtype, name
            np.testing.assert_array_equal(a, b, err_msg=name)
        monkeypatch.setenv(compiled.ENV_SWITCH, "0")
        slow, *slow_counts = reduce_in_view(mix, near, limit, lateral, bounds, s_period=period, **settings)
        assert tuple(slow_counts) == ref_counts
        np.testing.assert_array_equal(slow.labels, ref.labels)
        for name in ("weights", "means", "covs"):
            np.testing.assert_allclose(getattr(slow, name), getattr(ref, name), rtol=1e-9, atol=1e-9)
        kept = int(((near <= limit) & (lateral >= bounds[0]) & (lateral <= bounds[1]) & (mix.weights >= 1e-4)).sum())
        heavy = ref.labels[ref.weights >= 0.5]
        seen["pending"] += settings["same_label_distance"] is not None and len(set(heavy.tolist())) < len(heavy)
        seen["capped"] += len(ref) == 3 and settings["max_components"] == 3 and kept > 3
        seen["merged"] += len(ref) < kept
        seen["empty"] += n == 0
    assert all(seen.values()), seen


def test_compiled_reduce_in_view_at_the_limits(monkeypatch):
    """Exact limits: a range equal to the limit is in view, a lateral offset equal to a bound on the
    road, a weight equal to the prune threshold kept (one below it dropped), a pair at the merge gate's
    boundary (distance^2 = gate along one axis, times 1 -+ 1e-7) merged only inside it, and ``s`` of
    a lone component beyond the road's length (or below 0) taken modulo it; compiled and numpy alike."""
    from tracker.reduction import Mixture, reduce_in_view
    from tracker.ukf import Wrapping

    wrapping = Wrapping(angles=(3,), periods=((0, 300.0),))
    settings = dict(prune_threshold=1e-4, merge_gate=4.0, max_components=100, wrapping=wrapping,
                    same_label_distance=3.0, s_period=300.0)
    for factor in (1.0 - 1e-7, 1.0 + 1e-7):
        covs = np.broadcast_to(np.diag([2.0, 0.5, 1.0, 0.01, 0.01, 0.3, 0.05]), (6, 7, 7)).copy()
        means = np.zeros((6, 7))
        means[:, 5:] = 4.5, 1.9
        means[1, 0] = np.sqrt(4.0 * 2.0 * factor)  # at the gate from component 0
        means[2, 0], means[3, 0], means[4, 0], means[5, 0] = 450.0, -150.0, -200.0, 200.0
        weights = np.array([0.9, 0.6, 1e-4, np.nextafter(1e-4, 0.0), 0.3, 0.3])
        mix = Mixture(weights, means, covs, np.arange(6))
        near = np.array([50.0, 50.0, 50.0, 50.0, 60.0, np.nextafter(60.0, 61.0)])
        lateral = np.array([2.5, -3.0, 0.0, 0.0, 0.0, 0.0])
        results = {}
        for switch in ("0", "1"):
            monkeypatch.setenv(compiled.ENV_SWITCH, switch)
            results[switch] = reduce_in_view(mix, near, 60.0, lateral, (-3.0, 2.5), **settings)
        for got, left_view, off_road in results.values():
            assert (left_view, off_road) == (1, 0)
            assert sorted(got.labels.tolist()) == ([0, 2, 4] if factor < 1.0 else [0, 1, 2, 4])
            assert got.means[got.labels == 2, 0] == 150.0 and got.means[got.labels == 4, 0] == 100.0
        np.testing.assert_array_equal(results["0"][0].means, results["1"][0].means)


@pytest.mark.parametrize("seed", range(3))
def test_compiled_drop_inside_updated_equals_numpy(seed, monkeypatch):
    """``Tracker._drop_inside_updated`` by one compiled call (``inside_updated_kernel``) and by numpy
    (``points_in_rectangles`` with margin 0): random components of updated and idle labels around a
    few cars on a curved road, centres on the rectangles' edges too; the same mixture and counter (none
    dropped, some dropped)."""
    from tracker.reduction import Mixture

    rng = np.random.default_rng(seed)
    road = Road.from_curvature([(150.0, 0.0, 0.0), (300.0, 0.0, 1 / 120.0)], lanes=3, lane_width=3.5)
    ego = EgoState(*road.frame(np.array(40.0))[0], float(road.frame(np.array(40.0))[1]), 15.0, 0.0)
    outcomes = set()
    for _ in range(40):
        n = int(rng.integers(1, 14))
        means = np.column_stack([rng.choice([60.0, 80.0, 170.0], n) + rng.normal(0.0, 2.0, n), rng.normal(0.0, 2.0, n),
                                 rng.uniform(5, 20, n), rng.normal(0.0, 0.1, n), np.zeros(n), rng.uniform(3.0, 12.0, n),
                                 rng.uniform(1.6, 2.6, n), np.zeros(n)])
        edge = rng.random(n) < 0.3  # some centres on the heaviest one's front edge
        means[edge, :2] = means[0, :2] + [0.5 * means[0, 5], 0.0]
        labels = rng.integers(1, 7, n)
        mix = Mixture(rng.uniform(0.2, 1.0, n), means, np.broadcast_to(np.eye(8) * 0.1, (n, 8, 8)).copy(), labels)
        strong = set(rng.choice(np.arange(1, 7), 3, replace=False).tolist())
        results = []
        for switch in ("0", "1"):
            monkeypatch.setenv(compiled.ENV_SWITCH, switch)
            tracker = Tracker(road, TrackerConfig())
            tracker.mixture, tracker._strong_labels = mix, strong
            tracker._drop_inside_updated(ego)
            results.append((tracker.mixture, dict(tracker.stats)))
        (ref, ref_stats), (got, stats) = results
        assert stats == ref_stats
        for name in ("weights", "means", "covs", "labels"):
            np.testing.assert_array_equal(getattr(got, name), getattr(ref, name))
        outcomes.add(len(got) < n)
    assert outcomes == {True, False}


def test_absorb_candidates_kernel_equals_numpy():
    """``absorb_candidates_kernel`` against numpy's candidates of ``absorb_overlapping``: the heaviest
    component of each label among those of weight >= the threshold (weights at it, and ties of weight,
    which go in index order), heaviest first; none and one too."""
    from tracker.compiled.reduction import absorb_candidates_kernel

    rng = np.random.default_rng(3)
    for _ in range(200):
        n = int(rng.integers(0, 16))
        weights = rng.choice([0.2, 0.5, np.nextafter(0.5, 0.0), 0.7, 0.9], n)
        labels = rng.integers(1, 6, n)
        heavy = np.flatnonzero(weights >= 0.5)
        order = heavy[np.argsort(-weights[heavy], kind="stable")]
        _, first = np.unique(labels[order], return_index=True)
        np.testing.assert_array_equal(absorb_candidates_kernel(weights, labels.astype(np.int64), 0.5),
                                      order[np.sort(first)])


def _cluster_scene(seed: int, config: TrackerConfig, tracks: int | None = None):
    """A tracker with a random mixture and reported tracks, and the points, frame and predicted track
    rectangles its ``_cluster`` sees: overlapping track rectangles (duplicates of one vehicle), points in
    several rectangles, strays just outside them, blobs wide across the road (their lateral offsets are
    their y, with gaps to cut at), lone points (fragments) and radar detections older than the frame."""
    from tracker.frame import Frame, RadarDetections
    from tracker.measurement import Rectangles
    from tracker.motion import LENGTH
    from tracker.reduction import Mixture

    rng = np.random.default_rng(seed)
    road = Road.from_curvature([(300.0, 0.0, 0.0)], lanes=2, lane_width=3.5)
    tracker = Tracker(road, config)
    count = int(rng.integers(0, 7)) if tracks is None else tracks
    center = np.column_stack([rng.uniform(0.0, 60.0, count), rng.uniform(-5.0, 5.0, count)])
    if count > 2:
        center[1] = center[0] + rng.normal(0.0, 0.8, 2)  # a duplicate hypothesis of one vehicle
    psi = rng.normal(0.0, 0.2, count)
    length, width = rng.uniform(3.0, 12.0, count), rng.uniform(1.5, 2.6, count)
    rect = Rectangles(center, psi, np.zeros(count), length, width)
    parts = [rng.uniform([-5.0, -12.0], [70.0, 12.0], (int(rng.integers(1, 25)), 2))]  # clutter, lone points
    for k in range(count):  # each track's points, some a little outside (strays) or past its front
        u = rng.uniform(-0.5, 0.5 + rng.uniform(0.0, 0.6), int(rng.integers(1, 30))) * (length[k] + 2.0)
        v = rng.choice([-0.5, 0.5]) * width[k] + rng.normal(0.0, 0.3, len(u))
        parts.append(center[k] + np.column_stack([u * np.cos(psi[k]) - v * np.sin(psi[k]),
                                                  u * np.sin(psi[k]) + v * np.cos(psi[k])]))
    for _ in range(int(rng.integers(0, 5))):  # blobs up to 9 m across the road, their points 0.3-0.9 m apart
        across = np.cumsum(rng.uniform(0.3, 0.95, int(rng.integers(2, 14))))
        parts.append(np.column_stack([rng.uniform(0.0, 60.0) + rng.normal(0.0, 0.2, len(across)),
                                      rng.uniform(-8.0, 0.0) + across]))
    points = np.concatenate(parts)
    points = points[rng.permutation(len(points))]
    tracker._point_n = points[:, 1] + rng.normal(0.0, 0.05, len(points))
    extra = int(rng.integers(0, 6))
    labels = np.concatenate([rng.permutation(np.arange(1, count + 1)), rng.integers(1, count + 4, extra)])
    covs = np.tile(np.eye(tracker.dim), (count + extra, 1, 1))
    covs[:, LENGTH, LENGTH] = rng.uniform(0.0, 4.0, count + extra)
    tracker.mixture = Mixture(np.full(count + extra, 0.9), np.zeros((count + extra, tracker.dim)), covs, labels)
    tracker._reported = rng.permutation(count).astype(int)
    radar_count = int(rng.integers(0, 15))
    hits = points[rng.integers(0, len(points), radar_count)] + rng.normal(0.0, 1.0, (radar_count, 2))
    radar = RadarDetections(t=rng.uniform(0.9, 1.0, radar_count), x=hits[:, 0], y=hits[:, 1],
                            vx=rng.normal(10.0, 3.0, radar_count), vy=rng.normal(0.0, 1.0, radar_count))
    return tracker, points, Frame(1.0, EgoState(0.0, 0.0, 0.0, 10.0, 0.0), np.zeros((0, 2)), radar), rect


def _clustered(tracker, points, frame, rect) -> tuple:
    """``tracker._cluster``'s result and everything it sets, on a copy of the tracker's state."""
    import copy
    from collections import Counter

    tracker = copy.copy(tracker)
    tracker.stats = Counter()
    with compiled.pinned():
        clusters, velocities = tracker._cluster(points, frame, rect)
    return clusters, velocities, tracker._owned, tracker._component_group, tracker._free_radar, tracker.stats


def _assert_same_clusters(ref: tuple, got: tuple) -> None:
    """Two ``_clustered`` results bit for bit: the clusters' points and order, the velocities (the
    same rows or None), owners, component groups, free detections (values and dtypes) and stats."""
    assert len(ref[0]) == len(got[0])
    for a, b in zip(ref[0], got[0]):
        assert a.dtype == b.dtype and np.array_equal(a, b)
    assert [v is None for v in ref[1]] == [v is None for v in got[1]]
    for a, b in zip(ref[1], got[1]):
        assert a is None or (np.array_equal(a, b) and not b.flags.writeable)
    for a, b in zip(ref[2:5], got[2:5]):
        assert a.dtype == b.dtype and np.array_equal(a, b)
    assert ref[5] == got[5]


_CLUSTER_CONFIGS = {
    "default": {},
    "lenient-fragments": {"fragment_points": 3, "fragment_side_tolerance": None, "fragment_sigmas": 20.0},
    "min-points": {"min_points": 3, "split_gap": 0.2},
    "no-split-no-fragments": {"split_width": None, "fragment_points": None},
}


@pytest.mark.parametrize("settings", list(_CLUSTER_CONFIGS), ids=list(_CLUSTER_CONFIGS))
def test_compiled_clustering_equals_numpy(settings, monkeypatch):
    """``Tracker._cluster`` by ``cluster_points_kernel`` (and ``ordered_clusters_kernel`` after the
    fragments), ``cluster_radar_kernel``: the numpy path's clusters, velocities, owners, component
    groups, free detections and stats bit for bit, on random scenes (no tracks, overlapping track
    rectangles, strays, fragments, clusters cut across the road, more detections than clusters, none)."""
    from tracker.config import ClusteringConfig

    config = dataclasses.replace(TrackerConfig(), clustering=ClusteringConfig(**_CLUSTER_CONFIGS[settings]))
    seen = dict.fromkeys(("clusters_split", "fragment_points_adopted", "clusters_too_small", "clusters_fused"), 0)
    for seed in range(40):
        scene = _cluster_scene(seed, config, tracks=0 if seed < 3 else None)
        monkeypatch.setenv(compiled.ENV_SWITCH, "0")
        ref = _clustered(*scene)
        monkeypatch.setenv(compiled.ENV_SWITCH, "1")
        got = _clustered(*scene)
        _assert_same_clusters(ref, got)
        for name in seen:
            seen[name] += ref[5][name]
    assert seen["clusters_fused"] > 0
    assert (seen["clusters_split"] > 0) == (config.clustering.split_width is not None)
    if settings == "lenient-fragments":
        assert seen["fragment_points_adopted"] > 0
    if settings == "min-points":
        assert seen["clusters_too_small"] > 0


@pytest.mark.parametrize("case", ["one-point", "no-radar", "no-tracks", "nan-offset", "all-inside"])
def test_compiled_clustering_equals_numpy_at_the_edges(case, monkeypatch):
    """The same on the edges: one point, no radar detections, no tracks, a non-finite lateral offset
    (the kernel hands back: the numpy path runs), every point inside one rectangle."""
    from tracker.frame import Frame
    from tracker.measurement import Rectangles

    tracker, points, frame, rect = _cluster_scene(7, TrackerConfig(), tracks=0 if case == "no-tracks" else 3)
    if case == "one-point":
        points, tracker._point_n = points[:1], tracker._point_n[:1]
    if case == "no-radar":
        frame = Frame(frame.t, frame.ego, frame.lidar)
    if case == "nan-offset":
        tracker._point_n = tracker._point_n.copy()
        tracker._point_n[0] = np.nan
    if case == "all-inside":
        rect = Rectangles(np.array([[0.0, 0.0], [0.5, 0.0], [80.0, 0.0]]), np.zeros(3), np.zeros(3),
                          np.array([200.0, 3.0, 4.0]), np.array([40.0, 2.0, 2.0]))
    monkeypatch.setenv(compiled.ENV_SWITCH, "0")
    ref = _clustered(tracker, points, frame, rect)
    monkeypatch.setenv(compiled.ENV_SWITCH, "1")
    _assert_same_clusters(ref, _clustered(tracker, points, frame, rect))
    assert len(ref[0]) >= 1


def test_cluster_radar_ranges_equals_cluster_radar(monkeypatch):
    """``cluster_radar_ranges`` (one compiled call) against ``cluster_radar`` on the clusters' views: the
    same detection per cluster (its velocity row) and free detections, with and without kernels, for
    clusters of one point, more detections than clusters, detections exactly at the gate and none."""
    from tracker.clustering import cluster_radar, cluster_radar_ranges
    from tracker.frame import RadarDetections

    rng = np.random.default_rng(3)
    for trial in range(60):
        sizes = rng.integers(1, 6, int(rng.integers(1, 8)))
        edges = np.concatenate([[0], np.cumsum(sizes)])
        points = rng.uniform(0.0, 20.0, (int(edges[-1]), 2))
        count = int(rng.integers(0, 12))
        hits = points[rng.integers(0, len(points), count)] + rng.normal(0.0, 2.0, (count, 2))
        if count and trial % 3 == 0:
            hits[0] = points[0] + [3.0, 0.0]  # exactly at the gate
        radar = RadarDetections(t=np.full(count, 1.0), x=hits[:, 0], y=hits[:, 1], vx=rng.normal(size=count),
                                vy=rng.normal(size=count))
        keep = rng.random(len(sizes)) < 0.8
        lo, hi = edges[:-1][keep], edges[1:][keep]
        velocities, index = cluster_radar([points[a:b] for a, b in zip(lo, hi)], radar, 1.0, 3.0)
        free = np.setdiff1d(np.arange(count), index)
        for kernels in ("0", "1"):
            monkeypatch.setenv(compiled.ENV_SWITCH, kernels)
            got, got_free = cluster_radar_ranges(points, lo, hi, radar, 1.0, 3.0)
            assert [v is None for v in got] == [v is None for v in velocities]
            assert all(a is None or (np.array_equal(a, b) and not b.flags.writeable) for a, b in zip(velocities, got))
            assert got_free.dtype == np.int64 and np.array_equal(got_free, free)


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
