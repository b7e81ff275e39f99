"""Honest spreads (every shipped localizer but the image one): coasting on odometry with nothing
to see, the reported spread grows at least as fast as the odometry's own noise, and past
``max_spread_m`` the localizer stops claiming a pose."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tests.localizers.coasting import coast

#: (localizer, env id, env kwargs): each in a world of its sensor, crowd-free
CASES = [
    ("dead_reckoning", "crowdloc/RoboCupStatic-v0", {}),
    ("resection", "crowdloc/RoboCupStatic-v0", {}),
    ("kalman", "crowdloc/RoboCupStatic-v0", {}),
    ("mcl_bearing_paper", "crowdloc/RoboCupStatic-v0", {}),
    ("mcl_bearing", "crowdloc/RoboCupStatic-v0", {}),
    ("candidate_sets", "crowdloc/RoboCupStatic-v0", {}),
    ("mcl_lidar", "crowdloc/CrowdedRoom-v0", {"crowd_size": 0}),
    ("far_point_mcl", "crowdloc/CrowdedRoom-v0", {"crowd_size": 0}),
]
LOCALIZED, COASTING = 150, 300
#: the Monte Carlo reference and a particle set's sample spread are estimates: allow 20 % on the variance
SLACK = 0.8


def spread_limit(name: str, max_spread_m: float) -> dict:
    """The localizer parameters setting ``max_spread_m`` (far_point_mcl's is its MCL's)."""
    limit = {"max_spread_m": max_spread_m}
    return {"mcl": limit} if name == "far_point_mcl" else limit


@pytest.mark.parametrize(("name", "env_id", "kwargs"), CASES, ids=[c[0] for c in CASES])
def test_coasting_widens_the_spread_at_least_as_fast_as_the_odometry_noise(name: str, env_id: str, kwargs: dict) -> None:
    run = coast(name, env_id, LOCALIZED, COASTING, localizer_params=spread_limit(name, math.inf), **kwargs)
    valid = run.valid
    if not run.start.valid:
        assert not valid.any(), f"{name}: without a fix it must not claim one while coasting"
        return
    start_var = run.start.position_spread_m**2
    grown = run.spreads[valid] ** 2 - start_var
    needed = SLACK * run.reference[valid] ** 2
    short = grown < needed
    assert not short.any(), (
        f"{name}: coasting step {int(np.flatnonzero(valid)[short][0])}: the spread grew by "
        f"{math.sqrt(max(grown[short][0], 0)):.4f} m, the odometry noise alone by {math.sqrt(run.reference[valid][short][0] ** 2):.4f} m"
    )


@pytest.mark.parametrize(("name", "env_id", "kwargs"), CASES, ids=[c[0] for c in CASES])
def test_past_max_spread_a_coasting_localizer_claims_no_pose(name: str, env_id: str, kwargs: dict) -> None:
    free = coast(name, env_id, LOCALIZED, COASTING, localizer_params=spread_limit(name, math.inf), **kwargs)
    if not free.valid.any():
        return  # never claims a pose while coasting: nothing to limit
    limit = 0.5 * float(np.nanmax(free.spreads))
    limited = coast(name, env_id, LOCALIZED, COASTING, localizer_params=spread_limit(name, limit), **kwargs)
    spreads = np.array([e.position_spread_m for e in limited.estimates])
    assert not (limited.valid & (spreads > limit)).any(), f"{name}: claimed a pose with a spread over max_spread_m {limit:.3f}"
    assert not limited.valid[-1], f"{name}: still claims a pose at the end, spread {spreads[-1]:.3f} m > {limit:.3f} m"
