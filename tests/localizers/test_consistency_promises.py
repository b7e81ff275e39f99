"""Every localizer with a covariance keeps its consistency promise (``ConsistencyPromise``, a class
attribute beside its docstring): on a seeded run of its world, at least the promised share of the
steps with a pose lies inside the reported 95 % region."""

from __future__ import annotations

import importlib

import gymnasium as gym
import numpy as np
import pytest

import envs  # noqa: F401  (registers crowdloc/*)
from agents.evaluate import metrics
from agents.evaluate.consistency import POSE_DOF, run_nees
from agents.policies import make_policy
from localizers.base import ConsistencyPromise
from localizers.registry import BUILTIN_LOCALIZERS, LOCALIZERS


def promise_of(name: str) -> ConsistencyPromise | None:
    spec = LOCALIZERS[name]
    return getattr(getattr(importlib.import_module(spec.module), spec.cls), "consistency", None)


WITH_COVARIANCE = sorted(name for name in BUILTIN_LOCALIZERS if LOCALIZERS[name].covariance)


def test_every_localizer_with_a_covariance_makes_a_promise() -> None:
    assert not [name for name in WITH_COVARIANCE if promise_of(name) is None]


@pytest.mark.parametrize("name", WITH_COVARIANCE)
def test_a_seeded_run_keeps_the_promise(name: str) -> None:
    promise = promise_of(name)
    assert promise is not None
    env = gym.make(promise.env_id, localizer=name, prior="start")
    obs, info = env.reset(seed=0)
    policy = make_policy(promise.policy, env, seed=0)
    est, truth, cov = [], [], []
    for _ in range(promise.steps):
        action, _ = policy.predict(obs)
        obs, _, terminated, truncated, info = env.step(action)
        e = info["estimate"]
        if e.valid:
            est.append(e.as_array())
            truth.append(info["true_pose"])
            cov.append(e.covariance)
        if terminated or truncated:
            break
    env.close()
    assert len(est) >= 0.5 * promise.steps, f"{name}: a pose on only {len(est)} steps"
    fit = metrics.consistency(run_nees(name, np.array(est), np.array(truth), np.array(cov)), POSE_DOF)
    assert fit.inside_95 >= promise.inside_95, (name, fit.inside_95, fit.nees_median)


@pytest.mark.parametrize(("inside", "steps"), [(1.5, 100), (-0.1, 100), (0.5, 0)])
def test_a_promise_out_of_range_is_refused_naming_its_values(inside: float, steps: int) -> None:
    with pytest.raises(ValueError, match=f"got {inside}, {steps}"):
        ConsistencyPromise("crowdloc/RoboCupStatic-v0", "random_walk", steps, inside)
