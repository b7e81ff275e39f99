"""Map features as plug-ins: static scenery (a ceiling with its targets), registered by type name.

Built in: ``ceiling`` (:mod:`.ceiling`); ``buildings``, ``poles`` and ``trees``
(:mod:`.scenery`: static solids with an appearance); ``route`` (:mod:`.route`). See :mod:`.base`
for the interface.

This ``__init__`` imports the built-in modules, which registers them: Python runs it before any
module of the package, so whoever reaches the registry (:mod:`envs.config` imports only
:mod:`.base`) finds the built-in types.
"""

from __future__ import annotations

from envs.features.base import FEATURES, FacadeProfile, FeatureConfig, Solid, feature_types, register_feature
from envs.features.ceiling import CeilingConfig, CeilingTarget
from envs.features.route import RouteConfig
from envs.features.scenery import BuildingConfig, BuildingsConfig, FacadeConfig, PoleConfig, PolesConfig, TreeConfig, TreesConfig

__all__ = [
    "FEATURES",
    "BuildingConfig",
    "BuildingsConfig",
    "CeilingConfig",
    "CeilingTarget",
    "FacadeConfig",
    "FacadeProfile",
    "FeatureConfig",
    "PoleConfig",
    "PolesConfig",
    "RouteConfig",
    "Solid",
    "TreeConfig",
    "TreesConfig",
    "feature_types",
    "register_feature",
]
