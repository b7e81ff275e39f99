"""Map features as plug-ins: static scenery (a ceiling with its targets), registered by type name.

Built in: ``ceiling`` (:mod:`.ceiling`). See :mod:`.base` for the interface.
"""

from __future__ import annotations

from envs.features.base import FEATURES, FeatureConfig, feature_types, register_feature
from envs.features.ceiling import CeilingConfig, CeilingTarget

__all__ = ["FEATURES", "CeilingConfig", "CeilingTarget", "FeatureConfig", "feature_types", "register_feature"]
