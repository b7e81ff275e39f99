"""The input checks every localizer shares (localizers.base): same exception, message naming the localizer."""

from __future__ import annotations

import re

import numpy as np
import pytest

from envs.features import CeilingConfig, CeilingTarget
from localizers.base import (
    LandmarkMap,
    Localizer,
    MeasurementError,
    OdometryDelta,
    PoseEstimate,
    checked_dt,
    checked_odometry,
    require_reset,
)
from localizers.registry import LOCALIZERS, make_localizer

NAMES = sorted(LOCALIZERS)
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


def _ready(name: str) -> Localizer:
    loc = make_localizer(name, MAP, dt_s=0.1, params={"n_particles": 50} if "bearing" in name else None)
    loc.reset(np.random.default_rng(0), START)
    return loc


@pytest.mark.parametrize("name", NAMES)
def test_predict_and_update_before_reset_raise_naming_the_class(name: str) -> None:
    loc = make_localizer(name, MAP, dt_s=0.1)
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


@pytest.mark.parametrize("name", NAMES)
def test_odometry_of_the_wrong_type_raises(name: str) -> None:
    with pytest.raises(MeasurementError, match=rf"{name}: expected an OdometryDelta, got ndarray"):
        _ready(name).predict(np.zeros(3))  # type: ignore[arg-type]


def test_the_helpers() -> None:
    require_reset("X", True)
    with pytest.raises(RuntimeError, match=r"^X: call reset\(\)"):
        require_reset("X", False)
    assert checked_dt("X", 1) == 1.0 and isinstance(checked_dt("X", 1), float)
    d = checked_odometry("X", OdometryDelta(1e20, -2.0, 3.0))  # absurd but finite: passes
    assert d.dtype == np.float64 and d.tolist() == [1e20, -2.0, 3.0]
