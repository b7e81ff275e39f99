"""Crowds as plug-ins: one module per behaviour, registered by type name.

Built in: ``soccer`` (:mod:`.soccer`, owns the ball), ``queues`` (:mod:`.queues`),
``walkers`` (:mod:`.walkers`), ``corridor`` (:mod:`.corridor`: walkers both ways along a
corridor and groups standing by its walls) and ``campus`` (:mod:`.campus`: pedestrians on a
walkway network, groups by the doors, cars on the road's lanes, parked cars). See :mod:`.base` for the interface and
``docs/architecture.md`` for adding one.

This ``__init__`` imports the built-in modules, which registers them: Python runs it before any
module of the package, so whoever reaches the registry (:mod:`envs.config` imports only
:mod:`.base`) finds the built-in types. A crowd of your own registers itself when its module is
imported; neither this file nor :mod:`envs.config` names it.
"""

from __future__ import annotations

from envs.crowds.base import (
    CROWDS,
    BodySpec,
    Commands,
    Crowd,
    CrowdConfig,
    CrowdType,
    Taken,
    build_crowd,
    crowd_types,
    register_crowd,
)
from envs.crowds.campus import CampusConfig, CampusCrowd, LaneConfig, WalkwayConfig
from envs.crowds.corridor import CorridorConfig, CorridorCrowd
from envs.crowds.queues import QueueCrowd, QueuesConfig
from envs.crowds.soccer import SoccerConfig, SoccerCrowd
from envs.crowds.walkers import WalkerCrowd, WalkersConfig

__all__ = [
    "CROWDS",
    "BodySpec",
    "CampusConfig",
    "CampusCrowd",
    "Commands",
    "CorridorConfig",
    "CorridorCrowd",
    "Crowd",
    "CrowdConfig",
    "CrowdType",
    "LaneConfig",
    "QueueCrowd",
    "QueuesConfig",
    "SoccerConfig",
    "SoccerCrowd",
    "Taken",
    "WalkerCrowd",
    "WalkersConfig",
    "WalkwayConfig",
    "build_crowd",
    "crowd_types",
    "register_crowd",
]
