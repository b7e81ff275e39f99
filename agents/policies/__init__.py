"""The fixed policies (stable-baselines3's ``predict`` signature) and the driving code they share.

- :mod:`agents.policies.base`: :class:`FixedPolicy` and the helpers every policy uses;
- :mod:`agents.policies.fixed`: the baseline policies and their registry
  (:data:`FIXED_POLICIES`, :func:`make_policy`);
- :mod:`agents.policies.navigation`: the ceiling-target paper's corridor follower;
- :mod:`agents.policies.route_following`: pure pursuit along a world's route;
- :mod:`agents.policies.paths`: open-loop polygon paths as actions.

The names below are importable from ``agents.policies`` itself.

May import: ``envs``, ``localizers``, :mod:`agents.common`; never :mod:`agents.experiments`,
:mod:`agents.rl`, :mod:`agents.evaluate`, :mod:`agents.tune`, :mod:`agents.papers`.
"""

from agents.policies.base import check_command
from agents.policies.fixed import (
    CLEARANCE_M,
    FIXED_POLICIES,
    CorridorFollower,
    FixedPolicy,
    GreedyInformationGain,
    LandmarkSeeking,
    LookThenRoute,
    Observation,
    PatrolPath,
    RandomWalk,
    RouteFollower,
    SpinInPlace,
    StopAndGo,
    ceiling_targets,
    follows_routes,
    make_policy,
    read_estimate,
    register_policy,
    sonar_cones,
    task_route_kwargs,
)

__all__ = [
    "CLEARANCE_M",
    "FIXED_POLICIES",
    "CorridorFollower",
    "FixedPolicy",
    "GreedyInformationGain",
    "LandmarkSeeking",
    "LookThenRoute",
    "Observation",
    "PatrolPath",
    "RandomWalk",
    "RouteFollower",
    "SpinInPlace",
    "StopAndGo",
    "ceiling_targets",
    "check_command",
    "follows_routes",
    "task_route_kwargs",
    "make_policy",
    "read_estimate",
    "register_policy",
    "sonar_cones",
]
