"""The input checks every localizer shares (localizers.base): same exception, message naming the localizer."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from core.schema import ConfigError
from envs.features import CeilingConfig, CeilingTarget
from localizers.base import (
    LandmarkMap,
    Localizer,
    MeasurementError,
    OdometryDelta,
    PoseEstimate,
    checked_dt,
    checked_increment,
    checked_odometry,
    require_reset,
)
from localizers.far_landmark_pf.scene_map import SceneMap, geometry_fingerprint
from localizers.registry import BUILTIN_LOCALIZERS, LOCALIZERS, load_params, make_localizer

NAMES = sorted(BUILTIN_LOCALIZERS)  # not the toy plug-ins other test modules register
BOX = np.array([[0.0, 0.0, 10.0, 0.0], [10.0, 0.0, 10.0, 8.0], [10.0, 8.0, 0.0, 8.0], [0.0, 8.0, 0.0, 0.0]])
# with a ceiling feature too, for the localizers that read ceiling targets
CEILING = CeilingConfig(targets=(CeilingTarget("T0", 2.0, 5.0), CeilingTarget("T1", 6.0, 5.0, b="blue"))).map_data()
MAP = LandmarkMap(
    np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 8.0], [0.0, 8.0]]),
    ("a", "b", "c", "d"),
    (0.0, 0.0, 10.0, 8.0),
    BOX,
    {"ceiling": CEILING},
)
START = PoseEstimate(3.0, 4.0, 0.5, np.diag([0.01, 0.01, 0.001]))


_SCENE_MAP: dict[str, str] = {}  # far_landmark_pf's map of MAP (the fixture below writes it)


@pytest.fixture(autouse=True, scope="module")
def _scene_map(tmp_path_factory: pytest.TempPathFactory) -> None:
    scenes = SceneMap(np.array([[3.0, 4.0, 0.5]]), np.array([0, 2]), np.array([1, 4]), np.array([[4.0, 1.0], [5.0, -2.0]]), "box",
                      geometry_fingerprint(MAP))  # fmt: skip
    _SCENE_MAP["path"] = str(scenes.save(tmp_path_factory.mktemp("scenes") / "box.npz"))


def _params(name: str) -> dict[str, object] | None:
    """What a localizer needs beyond the map to be built here: fewer particles, a scene map."""
    if "bearing" in name:
        return {"n_particles": 50}
    if LOCALIZERS[name].measurement == "stereo_edges":
        return {"scene_map": _SCENE_MAP["path"]}
    return None


def _ready(name: str) -> Localizer:
    loc = make_localizer(name, MAP, dt_s=0.1, params=_params(name))
    loc.reset(np.random.default_rng(0), START)
    return loc


@pytest.mark.parametrize("name", NAMES)
def test_predict_and_update_before_reset_raise_naming_the_class(name: str) -> None:
    loc = make_localizer(name, MAP, dt_s=0.1, params=_params(name))
    text = rf"{LOCALIZERS[name].cls}: call reset\(\) before predict\(\) or update\(\)"
    with pytest.raises(RuntimeError, match=text):
        loc.predict(OdometryDelta(0.0, 0.0, 0.0))


@pytest.mark.parametrize("name", NAMES)
@pytest.mark.parametrize("dt_s", [0.0, -0.1, float("nan"), float("inf")])
def test_bad_dt_raises_naming_the_class_and_value(name: str, dt_s: float) -> None:
    with pytest.raises(ValueError, match=rf"{LOCALIZERS[name].cls}: dt_s must be a positive number of seconds, got {dt_s!r}"):
        make_localizer(name, MAP, dt_s=dt_s)


@pytest.mark.parametrize("name", NAMES)
@pytest.mark.parametrize("bad", [(np.nan, 0.0, 0.0), (0.0, np.inf, 0.0), (0.0, 0.0, -np.inf)])
def test_non_finite_odometry_raises_and_leaves_the_estimate(name: str, bad: tuple[float, float, float]) -> None:
    loc = _ready(name)
    loc.predict(OdometryDelta(0.05, 0.0, 0.01))
    before = loc.estimate
    text = re.escape(f"{name}: odometry increment {list(bad)} is not finite")
    with pytest.raises(MeasurementError, match=text):
        loc.predict(OdometryDelta(*bad))
    assert loc.estimate == before


@pytest.mark.parametrize(
    ("values", "fragment"),
    [(("a", 0.0, 0.0), "OdometryDelta.dx_m must be a number, got str 'a'"),
     ((0.0, None, 0.0), "OdometryDelta.dy_m must be a number, got NoneType None"),
     ((0.0, 0.0, True), "OdometryDelta.dtheta_rad must be a number, got bool True"),
     ((0.0, 0.0, "0.1"), "OdometryDelta.dtheta_rad must be a number, got str '0.1'")],
)  # fmt: skip
def test_odometry_delta_of_non_numbers_names_the_field(values: tuple[object, object, object], fragment: str) -> None:
    with pytest.raises(MeasurementError, match=re.escape(fragment)):
        OdometryDelta(*values)  # type: ignore[arg-type]
    assert OdometryDelta(np.float32(0.1), np.int64(0), 0).as_array().tolist() == [
        np.float32(0.1),
        0.0,
        0.0,
    ]  # numpy's numbers are numbers


@pytest.mark.parametrize("name", NAMES)
@pytest.mark.parametrize(
    "bad",
    [(1e20, 0.0, 0.0), (0.0, -1e20, 0.0), (1e300, 1e300, 0.0), (10.0, 8.5, 0.0), (0.0, 0.0, 1e20), (0.0, 0.0, -6.3)],
)
def test_absurd_odometry_raises_naming_the_bound_and_leaves_the_estimate(name: str, bad: tuple[float, float, float]) -> None:
    # the map is 10 m x 8 m: no step can translate more than its diagonal, or turn more than 2 pi
    loc = _ready(name)
    loc.predict(OdometryDelta(0.05, 0.0, 0.01))
    before = loc.estimate
    bound = math.hypot(10.0, 8.0)
    if np.hypot(bad[0], bad[1]) > bound:
        text = re.escape(
            f"{name}: odometry increment {list(bad)} translates {math.hypot(bad[0], bad[1])!r} m, more than the bound of {bound!r} m"
        )
    else:
        text = re.escape(f"{name}: odometry increment {list(bad)} turns {bad[2]!r} rad, more than a full turn (2 pi)")
    with pytest.raises(MeasurementError, match=text):
        loc.predict(OdometryDelta(*bad))
    assert loc.estimate == before
    loc.predict(OdometryDelta(0.05, 0.0, 0.01))  # and it goes on, with a finite pose where it has one
    assert not loc.estimate.valid or np.isfinite(loc.estimate.as_array()).all()


@pytest.mark.parametrize("name", NAMES)
def test_a_configured_step_bound_is_used(name: str) -> None:
    tight = LandmarkMap(MAP.positions_xy_m, MAP.names, MAP.bounds_m, MAP.walls_m, MAP.features, max_step_m=0.5)
    loc = make_localizer(name, tight, dt_s=0.1, params=_params(name))
    loc.reset(np.random.default_rng(0), START)
    loc.predict(OdometryDelta(0.3, 0.4, 0.0))  # exactly on the bound: accepted
    with pytest.raises(MeasurementError, match=re.escape(f"{name}: odometry increment [0.3, 0.5, 0.0] translates")):
        loc.predict(OdometryDelta(0.3, 0.5, 0.0))


@pytest.mark.parametrize("max_step_m", [0.0, -1.0, float("nan"), float("inf")])
def test_a_bad_step_bound_is_refused(max_step_m: float) -> None:
    with pytest.raises(ValueError, match=rf"LandmarkMap.max_step_m must be .* got {max_step_m!r}"):
        LandmarkMap(MAP.positions_xy_m, MAP.names, MAP.bounds_m, max_step_m=max_step_m)


@pytest.mark.parametrize("name", NAMES)
def test_odometry_of_the_wrong_type_raises(name: str) -> None:
    with pytest.raises(MeasurementError, match=rf"{name}: expected an OdometryDelta, got ndarray"):
        _ready(name).predict(np.zeros(3))  # type: ignore[arg-type]


def test_the_helpers() -> None:
    require_reset("X", True)
    with pytest.raises(RuntimeError, match=r"^X: call reset\(\)"):
        require_reset("X", False)
    assert checked_dt("X", 1) == 1.0 and isinstance(checked_dt("X", 1), float)
    d = checked_odometry("X", OdometryDelta(1e20, -2.0, 3.0))  # no bound given (a part without a map): passes
    assert d.dtype == np.float64 and d.tolist() == [1e20, -2.0, 3.0]
    assert checked_increment("X", OdometryDelta(3.0, 4.0, -2 * np.pi), 5.0) == (3.0, 4.0, -2 * np.pi)  # on the bounds
    with pytest.raises(
        MeasurementError, match=r"^X: odometry increment \[1e\+20, -2.0, 3.0\] translates 1e\+20 m, more than the bound of 5.0 m"
    ):
        checked_odometry("X", OdometryDelta(1e20, -2.0, 3.0), 5.0)
    assert MAP.step_limit_m == float(np.hypot(10.0, 8.0))


@pytest.mark.parametrize("bad", [0.0, -1.0, math.nan])
@pytest.mark.parametrize("name", [n for n in BUILTIN_LOCALIZERS if n != "far_point_mcl"])
def test_a_bad_claim_limit_is_refused_naming_it(name: str, bad: float) -> None:
    with pytest.raises(ConfigError, match=rf"max_spread_m must be > 0 m \(inf: no limit\), got {bad!r}"):
        load_params(name, {"max_spread_m": bad})


def test_far_point_mcls_claim_limit_is_its_mcls() -> None:
    assert load_params("far_point_mcl", {"mcl": {"max_spread_m": 0.3}}).mcl.max_spread_m == 0.3
    with pytest.raises(ConfigError, match="max_spread_m"):
        load_params("far_point_mcl", {"max_spread_m": 0.3})  # no second limit at the top level


# a size per localizer and its path in the parameters: each is refused at construction with the reason of
# its bound (n_particles 10**9 would otherwise end in numpy's MemoryError without naming the parameter)
SIZES = [
    ("mcl_lidar", {"n_particles": 10**9}, "LidarMCLParams.n_particles", "memory"),
    ("mcl_lidar", {"max_particles": 10**9}, "LidarMCLParams.max_particles", "memory"),
    ("mcl_lidar", {"recovery_candidates": 10**9}, "LidarMCLParams.recovery_candidates", "memory"),
    ("mcl_lidar", {"global_candidates": 10**9}, "LidarMCLParams.global_candidates", "memory"),
    ("mcl_lidar", {"table_directions": 10**6}, "LidarMCLParams.table_directions", "beam step"),
    ("far_point_mcl", {"mcl": {"n_particles": 10**9}}, "LidarMCLParams.n_particles", "memory"),
    ("far_point_mcl", {"filter": {"max_points": 10**9}}, "ScanFilterParams.max_points", "memory"),
    ("far_point_mcl", {"filter": {"bin_width_rad": 1e-9}}, "ScanFilterParams.bin_width_rad", "memory"),
    ("mcl_bearing", {"n_particles": 10**9}, "BearingMCLParams.n_particles", "memory"),
    ("mcl_bearing_paper", {"n_particles": 10**9}, "PaperMCLParams.n_particles", "memory"),
    ("far_landmark_pf", {"n_particles": 10**9}, "FarLandmarkParams.n_particles", "memory"),
    ("candidate_sets", {"candidates_per_arc": 10**9}, "CandidateSetParams.candidates_per_arc", "memory"),
    ("candidate_sets", {"max_live_candidates": 10**9}, "CandidateSetParams.max_live_candidates", "memory"),
    ("candidate_sets", {"max_sets": 10**9}, "CandidateSetParams.max_sets", "memory"),
]


@pytest.mark.parametrize(("name", "overrides", "field", "why"), SIZES)
def test_a_huge_size_is_refused_at_construction_naming_it_and_why(name: str, overrides: dict, field: str, why: str) -> None:
    with pytest.raises(ConfigError, match=rf"{re.escape(field)} must be at (most|least) [\d,]+.*\(.*{why}.*got"):
        load_params(name, overrides)


def test_the_largest_allowed_particle_set_is_accepted() -> None:
    from localizers.particles import MAX_PARTICLES

    assert load_params("mcl_lidar", {"n_particles": MAX_PARTICLES}).n_particles == MAX_PARTICLES


@pytest.mark.parametrize("name", ["far_point_mcl", "mcl_lidar"])
@pytest.mark.parametrize("order", ["descending", "repeated"])
def test_a_scan_whose_beam_angles_do_not_ascend_is_refused_naming_them(name: str, order: str) -> None:
    from localizers.base import ScanMeasurement

    loc = make_localizer(name, MAP, dt_s=0.1, params={"n_particles": 20} if name == "mcl_lidar" else {"mcl": {"n_particles": 20}})
    loc.reset(np.random.default_rng(0), START)
    angles = np.linspace(-1.0, 1.0, 11)
    angles = angles[::-1] if order == "descending" else np.r_[angles[:5], angles[4:-1]]
    source = "scan filter" if name == "far_point_mcl" else name  # far_point_mcl's scan filter reads the scan first
    message = rf"{source}: beam angles must ascend \(ScanMeasurement.angles_rad\), got -?[\d.]+ rad at index \d+ after"
    with pytest.raises(MeasurementError, match=message):
        loc.update(ScanMeasurement(np.full(11, 3.0), angles, 10.0))
