"""Same seeds, same numbers: short rollouts of every env id, recorded once and compared since.

``python -m tests.pinning record`` rewrites ``tests/data/pinned/rollouts.json`` from the code
as it is; do that only when a change of numbers is intended and explained. The tests
(``tests/envs/test_pinned.py`` and the reproductions' quick-run tests) compare against the
recorded files with :func:`assert_same_numbers`.
"""

from __future__ import annotations

import json
import math
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

import envs  # noqa: F401  (registers crowdloc/*)

PINNED_DIR = Path(__file__).resolve().parent / "data" / "pinned"
ROLLOUTS = PINNED_DIR / "rollouts.json"
STEPS = 90
RECORD_AT = (0, 1, 30, 60, 89)

#: (case name, env id, gym.make keywords): every id, each localizer family, the optional sensors
CASES: tuple[tuple[str, str, dict[str, Any]], ...] = (
    ("static_candidate_sets", "crowdloc/RoboCupStatic-v0", {"localizer": "candidate_sets", "crowd_size": 4}),
    ("static_kalman", "crowdloc/RoboCupStatic-v0", {"localizer": "kalman"}),
    ("crowded_mcl_bearing", "crowdloc/RoboCupCrowded-v0", {"localizer": "mcl_bearing", "crowd_size": 10}),
    (
        "crowded_active_conditions",
        "crowdloc/RoboCupCrowded-v0",
        {
            "localizer": "candidate_sets",
            "camera": {"fov_rad": math.pi / 2, "false_detection_probability": 0.05, "dropout_probability": 0.1},
            "sonar": {},
            "prior": "none",
            "belief_spread": True,
            "robot": {"slip_probability": 0.1},  # was odometry={...} before the sensor plug-ins
        },
    ),
    ("room_mcl_lidar", "crowdloc/CrowdedRoom-v0", {"localizer": "mcl_lidar", "lidar": {"beams": 271}}),
    ("room_far_point", "crowdloc/CrowdedRoom-v0", {"localizer": "far_point_mcl", "crowd": {"walkers": {"count": 4}}}),
    ("room_raw", "crowdloc/CrowdedRoom-v0", {"crowd_size": 30}),
)


def _summary(value: Any) -> list[float]:
    a = np.asarray(value, dtype=np.float64).reshape(-1)
    return [float(a.sum()), float((a * a).sum()), float(a[0]) if a.size else 0.0, float(a[-1]) if a.size else 0.0]


def rollout(env_id: str, kwargs: dict[str, Any], seed: int = 7) -> dict[str, Any]:
    """What a short seeded rollout shows: per recorded step, every observation array (sums,
    first and last entry), the true pose, the estimate and the contact count."""
    env = gym.make(env_id, **kwargs)
    actions = np.random.default_rng(seed).uniform(-1.0, 1.0, size=(STEPS, 2)).astype(np.float32)
    obs, info = env.reset(seed=seed)
    out: dict[str, Any] = {}
    contacts = 0
    for t in range(STEPS):
        if t:
            obs, _, _, _, info = env.step(actions[t])
            contacts += len(info["contacts"])
        if t in RECORD_AT:
            row: dict[str, Any] = {key: _summary(obs[key]) for key in sorted(obs)}
            row["true_pose"] = [float(v) for v in info["true_pose"]]
            row["contacts"] = contacts
            if "estimate" in info:
                est = info["estimate"]
                row["estimate"] = [est.x_m, est.y_m, est.theta_rad, float(est.valid)] if est.valid else [float(est.valid)]
            out[str(t)] = row
    env.close()
    return out


def record_rollouts() -> dict[str, Any]:
    return {name: rollout(env_id, kwargs) for name, env_id, kwargs in CASES}


#: a NEES this large comes from a collapsed particle set's near-singular covariance (condition
#: number ~1e10): it magnifies last-bit differences of the covariance, which differ between CPUs
#: (numba compiles for the host's vector units), by as much; measured: 3.8e-5 relative between two
#: machines on the LIDAR quick run. Such values are compared to NEES_LOOSE_REL, the rest to 1e-9.
NEES_SINGULAR = 1e6
NEES_LOOSE_REL = 1e-3


def _rel_tol(where: str, expected: float) -> float:
    key = where.rsplit(".", 1)[-1].split("[", 1)[0]
    return NEES_LOOSE_REL if key.startswith("nees") and abs(expected) >= NEES_SINGULAR else 1e-9


def assert_same_numbers(expected: Any, actual: Any, where: str = "", ignore: frozenset[str] = frozenset()) -> None:
    """Every number in ``expected`` equals the one at the same place in ``actual`` (to 1e-9
    relative, the print precision of the reports; a near-singular NEES to :data:`NEES_LOOSE_REL`);
    keys in ``ignore`` (timings) are skipped. ``actual`` may hold more keys than ``expected``."""
    if isinstance(expected, dict):
        assert isinstance(actual, dict), f"{where}: expected a mapping, got {actual!r}"
        for key, value in expected.items():
            if key in ignore:
                continue
            assert key in actual, f"{where}: key {key!r} is missing"
            assert_same_numbers(value, actual[key], f"{where}.{key}", ignore)
    elif isinstance(expected, list):
        assert isinstance(actual, list) and len(actual) == len(expected), f"{where}: expected {expected!r}, got {actual!r}"
        for i, (e, a) in enumerate(zip(expected, actual)):
            assert_same_numbers(e, a, f"{where}[{i}]", ignore)
    elif isinstance(expected, bool) or expected is None or isinstance(expected, str):
        assert expected == actual, f"{where}: expected {expected!r}, got {actual!r}"
    elif isinstance(expected, (int, float)):
        assert isinstance(actual, (int, float)), f"{where}: expected {expected!r}, got {actual!r}"
        if math.isnan(expected):
            assert math.isnan(actual), f"{where}: expected nan, got {actual!r}"
        else:
            tol = _rel_tol(where, expected)
            assert math.isclose(expected, actual, rel_tol=tol, abs_tol=1e-12), f"{where}: expected {expected!r}, got {actual!r}"
    else:
        raise TypeError(f"{where}: cannot compare {type(expected).__name__}")


def iter_cases() -> Iterator[tuple[str, str, dict[str, Any]]]:
    yield from CASES


if __name__ == "__main__":
    if sys.argv[1:] != ["record"]:
        sys.exit("usage: python -m tests.pinning record")
    PINNED_DIR.mkdir(parents=True, exist_ok=True)
    ROLLOUTS.write_text(json.dumps(record_rollouts(), indent=1) + "\n")
    print(f"wrote {ROLLOUTS}")
