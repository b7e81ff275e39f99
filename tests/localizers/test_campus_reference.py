"""The campus's LIDAR reference: ``mcl_lidar`` in its likelihood-field configuration (ROS amcl's
model) on the 360 deg 100 m LIDAR localizes the robot along the route among people and cars,
as the far-landmark paper's amcl reference did."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np

import envs  # noqa: F401  (registers crowdloc/*)
from agents.policies import make_policy

#: ROS amcl's model, without recovery or lost detection, as amcl runs by default: injection drawn
#: uniformly over a 150 m x 100 m campus almost never lands near the robot (mcl_lidar's docstring),
#: and the lost test (the likelihood falling below its average) fires when people pass, after
#: which no pose is claimed, the route follower stands, and a filter updated on motion never updates again
AMCL_LIKE = {
    "model": "likelihood_field", "table_resolution_m": 0.1, "beam_stride": 8, "sampling": 1.0, "recovery": False, "lost_ratio": 0.0,
}  # fmt: skip


def test_likelihood_field_mcl_tracks_the_route_among_a_crowd() -> None:
    env = gym.make("crowdloc/StereoCampus-v0", crowd_size=30, localizer="mcl_lidar", localizer_params=AMCL_LIKE, prior="start")
    obs, info = env.reset(seed=3)
    policy = make_policy("route_follower", env, seed=0)
    errors, valid = [], 0
    for _ in range(600):  # 60 s: down the sidewalk, the turn, into the mall
        action, _ = policy.predict(obs)
        obs, _, terminated, truncated, info = env.step(action)
        est = info["estimate"]
        if est.valid:
            valid += 1
            errors.append(math.hypot(est.x_m - info["true_pose"][0], est.y_m - info["true_pose"][1]))
        if terminated or truncated:
            break
    # it drove on (the route follower plans on this estimate) and stayed on the truth
    assert math.hypot(info["true_pose"][0] - 110.0, info["true_pose"][1] - 31.0) > 30.0
    assert valid >= 0.95 * len(errors) and len(errors) > 500
    assert np.median(errors) < 0.15 and max(errors) < 0.6, (np.median(errors), max(errors))
