"""The entry point behind every registered id."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import gymnasium as gym

from envs.localization_env import LocalizationEnv


def make_env(
    world: str,
    render_mode: str | None = None,
    localizer: str | None = None,
    localizer_params: Mapping[str, Any] | None = None,
    prior: str | None = None,
    belief_spread: bool | None = None,
    localizer_sensor: str | None = None,
    **kwargs: Any,
) -> gym.Env[Any, Any]:
    """Build a :class:`LocalizationEnv` for a shipped world with keyword overrides.

    Args:
        world: shipped world name.
        render_mode: ``None``, ``"rgb_array"`` or ``"human"``.
        localizer: a registered localizer name; the env then comes wrapped in
            :class:`envs.wrappers.LocalizationObservation` (estimate in the observation).
        localizer_params: overrides of that localizer's parameters.
        prior: ``"start"`` or ``"none"``: whether the localizer gets the true start pose.
        belief_spread: also observe the spread of the localizer's hypotheses (default false).
        localizer_sensor: the sensor the localizer reads where the world has several of its kind.
        **kwargs: world overrides (``crowd_size``, ``camera={...}``, ...).
    """
    env = LocalizationEnv(world=world, render_mode=render_mode, **kwargs)
    if localizer is None:
        if localizer_params is not None or prior is not None or belief_spread is not None or localizer_sensor is not None:
            raise ValueError("localizer_params, prior, belief_spread and localizer_sensor need a localizer=... name")
        return env
    from envs.wrappers import LocalizationObservation  # the localizers load only when a localizer is asked for

    spread = False if belief_spread is None else belief_spread
    return LocalizationObservation(env, localizer, localizer_params, prior, spread, localizer_sensor)
