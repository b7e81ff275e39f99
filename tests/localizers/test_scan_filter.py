"""Tests of localizers.scan_filter: far-point extraction against a brute-force reference,
accumulation under known odometry and its travel window, the beam-format mapping, the
paper's effect (people in front of walls removed), and far_point_mcl."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from core.geometry import between, compose, wrap_angle
from core.motion import sample_odometry
from core.raycast import cast_rays
from core.schema import ConfigError, from_mapping, load_yaml
from localizers.base import LandmarkMap, Localizer, MeasurementError, OdometryDelta, PoseEstimate, ScanMeasurement
from localizers.bounds import odometry_process_noise
from localizers.mcl_lidar import LidarMCLParams
from localizers.registry import load_params, make_localizer
from localizers.scan_filter import FarPointMCL, FarPointMCLParams, ScanFilter, ScanFilterParams, angular_bins, far_points

CONFIGS = Path(__file__).resolve().parents[2] / "configs" / "localizers"
ROOM = np.array([[0, 0, 7, 0], [7, 0, 7, 7], [7, 7, 0, 7], [0, 7, 0, 0]], dtype=np.float64)
BEAMS = np.linspace(-0.75 * math.pi, 0.75 * math.pi, 1081)
MAX_RANGE = 30.0


def ranges_from(pose: np.ndarray, centres: np.ndarray | None = None, radii: np.ndarray | None = None) -> np.ndarray:
    """Noise-free UTM-30LX ranges in the 7 m room, with optional circular people."""
    c = np.zeros((0, 2)) if centres is None else np.asarray(centres, dtype=np.float64)
    r = np.zeros(0) if radii is None else np.asarray(radii, dtype=np.float64)
    return cast_rays(
        np.asarray(pose[:2], dtype=np.float64), BEAMS + pose[2], MAX_RANGE,
        np.ascontiguousarray(ROOM[:, :2]), np.ascontiguousarray(ROOM[:, 2:]), c, r,
    )  # fmt: skip


def wall_distance(points_xy: np.ndarray) -> np.ndarray:
    """Distance of world points to the nearest wall of the 7 m room (inside it)."""
    x, y = points_xy[:, 0], points_xy[:, 1]
    return np.minimum.reduce([np.abs(x), np.abs(x - 7.0), np.abs(y), np.abs(y - 7.0)])


def scan_at(pose: np.ndarray, **people: np.ndarray) -> ScanMeasurement:
    return ScanMeasurement(ranges_from(pose, **people), BEAMS.copy(), MAX_RANGE)


# --- far-point extraction ------------------------------------------------------------------


def squared_distances(x: np.ndarray, y: np.ndarray, origin: tuple[float, float]) -> list[float]:
    out = []
    for xi, yi in zip(x, y):
        dx, dy = float(xi) - origin[0], float(yi) - origin[1]
        out.append(dx * dx + dy * dy)  # the same float64 operations as the kernel
    return out


def brute_force_far_points(x: np.ndarray, y: np.ndarray, origin: tuple[float, float], heading: float, bins: int) -> np.ndarray:
    """Largest squared distance per bin (-1 where empty), one point at a time."""
    best = np.full(bins, -1.0)
    for j, d2 in zip(angular_bins(x - origin[0], y - origin[1], heading, bins), squared_distances(x, y, origin)):
        best[j] = max(best[j], d2)
    return best


coordinate = st.floats(-20.0, 20.0, allow_nan=False, allow_infinity=False)


@settings(max_examples=150, deadline=None)
@given(
    points=st.lists(st.tuples(coordinate, coordinate), min_size=0, max_size=300),
    origin=st.tuples(st.floats(-5, 5), st.floats(-5, 5)),
    heading=st.floats(-10.0, 10.0),
    bins=st.integers(1, 400).map(lambda b: 2 * b),
)
def test_far_points_keep_exactly_the_farthest_point_of_each_bin(
    points: list[tuple[float, float]], origin: tuple[float, float], heading: float, bins: int
) -> None:
    pts = np.array(points, dtype=np.float64).reshape(-1, 2)
    index, dist = far_points(pts[:, 0], pts[:, 1], origin, heading, bins)
    reference = brute_force_far_points(pts[:, 0], pts[:, 1], origin, heading, bins)
    np.testing.assert_array_equal(index >= 0, reference >= 0)  # the same bins are occupied
    filled = index >= 0
    chosen = squared_distances(pts[index[filled], 0], pts[index[filled], 1], origin)
    np.testing.assert_array_equal(chosen, reference[filled])  # the farthest point (ties: any of them)
    np.testing.assert_allclose(dist[filled], np.sqrt(reference[filled]), rtol=1e-15)
    assert np.isnan(dist[~filled]).all()
    # each chosen point lies in its own bin
    rel = pts[index[filled]] - np.asarray(origin)
    np.testing.assert_array_equal(angular_bins(rel[:, 0], rel[:, 1], heading, bins), np.flatnonzero(filled))


@pytest.mark.parametrize("heading", [0.0, 1.0, -3.0, 40.0])
def test_bin_j_is_centred_on_relative_direction_j(heading: float) -> None:
    bins = 1440
    j = np.arange(bins)
    for offset in (0.0, 0.49, -0.49):  # within half a bin of the centre
        direction = heading + (j + offset) * 2 * math.pi / bins
        np.testing.assert_array_equal(angular_bins(np.cos(direction), np.sin(direction), heading, bins), j)


def test_far_points_of_a_ring_behind_a_person() -> None:
    # a wall ring at 5 m and a person's points at 1 m in the first quadrant
    a = np.linspace(-math.pi, math.pi, 3600, endpoint=False)
    wall = np.stack([5 * np.cos(a), 5 * np.sin(a)], 1)
    person = np.stack([np.cos(a[900:1000]), np.sin(a[900:1000])], 1)
    pts = np.vstack([person, wall, person])
    _, dist = far_points(pts[:, 0], pts[:, 1], (0.0, 0.0), 0.0, 360)
    np.testing.assert_allclose(dist, 5.0)


# --- accumulation --------------------------------------------------------------------------


def test_accumulated_points_are_the_world_points_in_the_odometry_frame() -> None:
    """Exact odometry, the robot translating along x: each scan's hit points land where the
    room's walls are, expressed in the frame of the start pose."""
    start = np.array([1.5, 2.0, 0.3])
    filt = ScanFilter(ScanFilterParams(travel_m=10.0))
    filt.reset()
    pose = start.copy()
    expected = []
    for k in range(12):
        if k:
            delta = np.array([0.05, 0.0, 0.0])
            filt.predict(OdometryDelta(*delta))
            pose = compose(pose, delta)
        r = ranges_from(pose)
        filt.add_scan(ScanMeasurement(r, BEAMS, MAX_RANGE))
        hit = r < MAX_RANGE
        world = np.stack([pose[0] + r[hit] * np.cos(BEAMS[hit] + pose[2]), pose[1] + r[hit] * np.sin(BEAMS[hit] + pose[2])], 1)
        expected.append(between(start, np.hstack([world, np.zeros((world.shape[0], 1))]))[:, :2])
    np.testing.assert_allclose(filt.points_xy, np.vstack(expected), atol=1e-9)
    np.testing.assert_allclose(filt.odometry_pose, between(start, pose), atol=1e-12)
    # and back to the world through the true pose: on the walls
    world = filt.to_world(filt.points_xy, pose)
    assert wall_distance(world).max() < 1e-9


def test_points_older_than_the_travel_window_are_dropped() -> None:
    filt = ScanFilter(ScanFilterParams(travel_m=0.25))
    filt.reset()
    counts = []
    pose = np.array([2.0, 3.0, 0.0])
    for k in range(8):
        if k:
            filt.predict(OdometryDelta(0.1, 0.0, 0.0))
            pose[0] += 0.1
        s = scan_at(pose)
        counts.append(int(np.count_nonzero(s.ranges_m < MAX_RANGE)))
        filt.add_scan(s)
        # scans at travel T, T - 0.1, T - 0.2 are within 0.25 m; T - 0.3 is not
        assert filt.points_xy.shape[0] == sum(counts[-3:])
    assert filt.travel_m == pytest.approx(0.7)


def test_the_window_increment_runs_from_the_oldest_scan_kept_to_now() -> None:
    filt = ScanFilter(ScanFilterParams(travel_m=0.25))
    filt.reset()
    np.testing.assert_array_equal(filt.window_increment, np.zeros(3))  # nothing kept yet
    poses = [np.zeros(3)]
    for k in range(6):
        if k:
            d = np.array([0.1, 0.02, 0.1])
            filt.predict(OdometryDelta(*d))
            poses.append(compose(poses[-1], d))
        filt.add_scan(scan_at(np.array([3.0, 3.0, 0.0])))
        oldest = poses[max(0, k - 2)]  # scans at travel T, T - 0.1, T - 0.2 (about) are kept
        np.testing.assert_allclose(filt.window_increment, between(oldest, poses[-1]), atol=1e-12)


def test_the_reported_covariance_adds_a_third_of_the_windows_odometry_noise_at_the_last_fix() -> None:
    m = LidarMCLParams()
    out = []
    for window_error in (True, False):
        loc = FarPointMCL(room_map(), FarPointMCLParams(window_error=window_error), dt_s=0.025)
        loc.reset(np.random.default_rng(0), PoseEstimate(3.0, 3.0, 0.0, np.diag([1e-3, 1e-3, 1e-3])))
        added = None
        for k in range(40):
            if k:
                loc.predict(OdometryDelta(0.02, 0.0, 0.01))
            updates = loc.updates
            loc.update(scan_at(np.array([3.0 + 0.02 * k, 3.0, 0.01 * k])))
            if loc.updates > updates:  # a fix: what the window's odometry adds until the next
                window = loc.filter.window_increment
                start = compose(loc.mcl.estimate.as_array(), between(window, np.zeros(3)))
                added = odometry_process_noise(start, window, m.alphas, min_translation_std_m=m.min_translation_std_m,
                                               min_rotation_std_rad=m.min_rotation_std_rad) / 3.0  # fmt: skip
                window_at_fix = window
        out.append((loc.estimate, added, loc.updates))
    (on, added, updates), (off, _, _) = out
    assert updates == 2 and window_at_fix[0] > 0.4  # the fix at the start, and one after 0.5 m on a full window
    assert on.as_array().tolist() == off.as_array().tolist()  # the estimate itself is the same
    np.testing.assert_allclose(on.covariance, off.covariance + added, rtol=1e-9)


def test_turning_in_place_keeps_points_until_the_cap() -> None:
    filt = ScanFilter(ScanFilterParams(travel_m=0.5, max_points=3000))
    filt.reset()
    for _ in range(5):
        filt.predict(OdometryDelta(0.0, 0.0, 0.2))
        filt.add_scan(scan_at(np.array([3.5, 3.5, 0.0])))
    assert filt.travel_m == 0.0
    assert filt.points_xy.shape[0] <= 3000
    assert filt.points_xy.shape[0] >= 3000 - 1081  # whole scans are dropped, oldest first


def test_reset_forgets_everything() -> None:
    filt = ScanFilter(ScanFilterParams())
    filt.predict(OdometryDelta(0.3, 0.0, 0.1))
    filt.add_scan(scan_at(np.array([3.0, 3.0, 0.0])))
    filt.reset()
    assert filt.points_xy.shape == (0, 2) and filt.travel_m == 0.0
    np.testing.assert_array_equal(filt.odometry_pose, np.zeros(3))
    out = filt.extract(BEAMS, MAX_RANGE)
    np.testing.assert_array_equal(out.ranges_m, MAX_RANGE)  # nothing accumulated: empty bins


# --- the beam format -------------------------------------------------------------------------


def test_extraction_in_the_sensors_beam_format_equals_the_scan_of_the_empty_room() -> None:
    pose = np.array([3.0, 3.5, 0.4])
    filt = ScanFilter(ScanFilterParams())
    processed = filt.update(scan_at(pose))
    np.testing.assert_array_equal(processed.angles_rad, BEAMS)
    assert processed.max_range_m == MAX_RANGE
    # one static scan, 0.25 deg bins centred on the beams: each beam reads its own point
    np.testing.assert_allclose(processed.ranges_m, ranges_from(pose), rtol=1e-12)


def test_empty_bins_read_max_range_and_long_points_are_clipped() -> None:
    filt = ScanFilter(ScanFilterParams(bin_width_rad=math.radians(1.0)))  # bin j centred on j deg
    filt.add_scan(ScanMeasurement(np.array([29.9, MAX_RANGE, 2.0]), np.radians([0.0, 10.0, 20.0]), MAX_RANGE))
    filt.predict(OdometryDelta(-0.5, 0.0, 0.0))  # backing away: the 29.9 m point is now 30.4 m off
    out = filt.extract(np.radians([0.0, 10.0, 16.0, 20.0]), MAX_RANGE)
    # 0 deg: clipped; 10 deg: no hit; the 20 deg point is now seen at 16.04 deg, in bin 16
    moved = (0.5 + 2.0 * math.cos(math.radians(20)), 2.0 * math.sin(math.radians(20)))
    assert math.degrees(math.atan2(moved[1], moved[0])) == pytest.approx(16.04, abs=0.01)
    np.testing.assert_allclose(out.ranges_m, [MAX_RANGE, MAX_RANGE, math.hypot(*moved), MAX_RANGE], rtol=1e-12)
    # wider bins than the beam spacing: neighbouring beams share a point
    wide = ScanFilter(ScanFilterParams(bin_width_rad=math.radians(5.0)))
    wide.add_scan(ScanMeasurement(np.array([3.0, 3.0]), np.radians([0.0, 1.0]), MAX_RANGE))
    out = wide.extract(np.radians([0.0, 1.0, 2.0, 3.0]), MAX_RANGE)
    np.testing.assert_allclose(out.ranges_m, [3.0, 3.0, 3.0, MAX_RANGE], rtol=1e-12)


def test_far_points_remove_people_in_front_of_the_walls() -> None:
    """The paper's effect: queues along the side walls hide parts of them from every single
    scan; over 0.5 m of travel each part shows between people, and the far points recover it."""
    rng = np.random.default_rng(0)
    filt = ScanFilter(ScanFilterParams(travel_m=0.5))
    people_y = np.arange(0.6, 6.6, 0.45)
    pose = np.array([2.5, 3.5, 0.0])
    for k in range(41):  # 0.5 m at 0.15 m/s in 40 Hz steps would be 133 scans; 0.0125 m steps here
        if k:
            filt.predict(OdometryDelta(0.0125, 0.0, 0.0))
            pose[0] += 0.0125
        # people stand 0.3 m off the side walls and shuffle a little
        centres = np.vstack(
            [np.stack([np.full(people_y.size, 0.3), people_y + 0.05 * rng.standard_normal(people_y.size)], 1),
             np.stack([np.full(people_y.size, 6.7), people_y + 0.05 * rng.standard_normal(people_y.size)], 1)]
        )  # fmt: skip
        scan = scan_at(pose, centres=centres, radii=np.full(centres.shape[0], 0.18))
        processed = filt.update(scan)
    empty = ranges_from(pose)
    raw, far = np.abs(scan.ranges_m - empty), np.abs(processed.ranges_m - empty)
    assert (raw > 0.2).mean() > 0.25  # a single scan: over a quarter of the beams end on people
    # far points: half as many (the rest is wall seen so obliquely that the queue closes every gap)
    assert (far > 0.2).mean() < 0.5 * (raw > 0.2).mean(), ((far > 0.2).mean(), (raw > 0.2).mean())
    assert far.mean() < 0.5 * raw.mean()


# --- far_point_mcl ---------------------------------------------------------------------------


def room_map() -> LandmarkMap:
    return LandmarkMap(np.zeros((0, 2)), (), (0.0, 0.0, 7.0, 7.0), ROOM)


def test_far_point_mcl_tracks_among_people_and_draws_its_points() -> None:
    poses = np.stack([np.linspace(2.0, 5.0, 121), np.full(121, 3.0), np.zeros(121)], 1)
    params = FarPointMCLParams(mcl=LidarMCLParams(update_min_travel_m=0.1, beam_stride=2), filter=ScanFilterParams(travel_m=0.5))
    loc = FarPointMCL(room_map(), params, dt_s=0.025)
    assert isinstance(loc, Localizer)
    loc.reset(np.random.default_rng(0), PoseEstimate(*poses[0], np.diag([0.01, 0.01, 0.003])))
    rng = np.random.default_rng(1)
    people = np.stack([np.full(14, 0.35), np.linspace(0.5, 6.5, 14)], 1)
    for k in range(poses.shape[0]):
        if k:
            loc.predict(OdometryDelta(*sample_odometry(rng, between(poses[k - 1], poses[k]), [0.01, 0.005, 0.005, 0.005])))
        loc.update(scan_at(poses[k], centres=people, radii=np.full(14, 0.18)))
    est = loc.estimate
    assert math.hypot(est.x_m - poses[-1, 0], est.y_m - poses[-1, 1]) < 0.1
    assert abs(float(wrap_angle(est.theta_rad - poses[-1, 2]))) < 0.03
    assert loc.mcl.updates >= 25  # every 0.1 m of 3 m
    ov = loc.overlay()
    assert ov.poses.shape == (1000, 3)
    assert ov.points_xy.shape[0] > filt_points(loc)  # accumulated plus far points
    # placed by the estimate: the far points of the walls lie near the walls of the world
    far = loc.filter.to_world(loc.filter.far_points_xy, est.as_array())
    assert np.median(wall_distance(far)) < 0.05


def filt_points(loc: FarPointMCL) -> int:
    return int(loc.filter.points_xy.shape[0])


def test_far_point_mcl_extracts_only_when_the_mcl_is_due() -> None:
    loc = FarPointMCL(room_map(), FarPointMCLParams(), dt_s=0.025)
    loc.reset(np.random.default_rng(0), PoseEstimate(3.0, 3.0, 0.0, np.diag([1e-4, 1e-4, 1e-4])))
    loc.update(scan_at(np.array([3.0, 3.0, 0.0])))
    assert loc.mcl.updates == 1
    for k in range(1, 20):  # 0.25 m: the paper's 0.5 m is not reached
        loc.predict(OdometryDelta(0.0125, 0.0, 0.0))
        loc.update(scan_at(np.array([3.0 + 0.0125 * k, 3.0, 0.0])))
    assert loc.mcl.updates == 1
    assert loc.filter.points_xy.shape[0] == 20 * 1081


def test_bad_scan_raises_naming_value_and_index() -> None:
    loc = FarPointMCL(room_map(), FarPointMCLParams(), dt_s=0.025)
    loc.reset(np.random.default_rng(0))
    ranges = np.full(1081, 3.0)
    ranges[42] = np.nan
    with pytest.raises(MeasurementError, match=r"scan filter: range nan m at index 42"):
        loc.update(ScanMeasurement(ranges, BEAMS, MAX_RANGE))
    ranges[42] = -1.0
    with pytest.raises(MeasurementError, match=r"range -1\.0 m at index 42"):
        ScanFilter(ScanFilterParams()).add_scan(ScanMeasurement(ranges, BEAMS, MAX_RANGE))
    with pytest.raises(MeasurementError, match=r"equal length, got shapes \(1081,\) and \(1080,\)"):
        loc.update(ScanMeasurement(np.full(1081, 3.0), BEAMS[1:], MAX_RANGE))
    with pytest.raises(MeasurementError, match="not finite"):
        loc.predict(OdometryDelta(0.0, np.inf, 0.0))


def test_nested_params_from_the_registry() -> None:
    path = CONFIGS / "far_point_mcl.yaml"
    assert from_mapping(FarPointMCLParams, load_yaml(path), where=str(path)) == FarPointMCLParams()
    p = load_params("far_point_mcl", {"mcl": {"sampling": 0.6}, "filter": {"travel_m": 1.0}})
    assert p.mcl.sampling == 0.6 and p.mcl.hit_std_m == FarPointMCLParams().mcl.hit_std_m  # merged key by key
    assert p.filter.travel_m == 1.0 and p.filter.bin_width_rad == pytest.approx(math.radians(0.25))
    loc = make_localizer("far_point_mcl", room_map(), dt_s=0.025, params={"filter": {"travel_m": 1.0}})
    assert isinstance(loc, FarPointMCL) and loc.filter.params.travel_m == 1.0


@pytest.mark.parametrize(
    ("overrides", "needle"),
    [
        ({"filter": {"travel_m": -0.5}}, "travel_m must be >= 0"),
        ({"filter": {"bin_width_rad": 0.0}}, r"bin_width_rad must be in \(0, pi\]"),
        ({"filter": {"bins": 10}}, "unknown key 'bins'"),
        ({"mcl": {"hit": 0.5}}, "unknown key 'hit'"),
        ({"travel_m": 0.5}, "unknown key 'travel_m'"),
    ],
)
def test_bad_params_name_the_key(overrides: dict, needle: str) -> None:
    with pytest.raises(ConfigError, match=needle):
        load_params("far_point_mcl", overrides)


def test_bins_fill_the_turn() -> None:
    assert ScanFilterParams(bin_width_rad=math.radians(0.25)).bins == 1440
    assert ScanFilterParams(bin_width_rad=1.0).bins == 6  # rounded: 2 pi / 6 wide
