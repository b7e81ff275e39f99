"""The goal metrics of a world with a ``goal`` (the corridor's last target, the campus route's end).

Such a world ends an episode itself (``terminated``) on the step the robot has stood still at its
goal for the goal's hold time (``envs.localization_env.LocalizationEnv._at_goal``); an episode
that does not get there ends at the evaluation's ``episode_steps`` (truncated). Per episode:

- ``goal_missed``: 0 if the world ended the episode at its goal, 1 if the episode ran out first
  (the tables' mean is the share of episodes that did not reach the goal; lower is better);
- ``time_to_goal_s``: seconds from the reset to that step, hold time included. **Never reached**:
  NaN, not the episode's length: a time the robot never achieved would make a policy that gives
  up look as fast as one that arrives at the last step. The tables average the episodes that
  reached the goal and say how many (``k/N``); ``goal_missed`` counts the others, so the two
  are read together.

A world without a goal has neither row (:attr:`agents.evaluate.spec.EvalSpec.metrics`).
"""

from __future__ import annotations

import math

from agents.evaluate.plugins import MetricInfo, Track

#: the goal metrics, after the core ones in the tables (only for a world with a goal)
GOAL_METRICS: tuple[MetricInfo, ...] = (
    MetricInfo("goal_missed", "goal not reached (share of episodes)", "{:.2f}"),
    MetricInfo("time_to_goal_s", "time to goal [s] (episodes that reached it)", "{:.2f}"),
)

#: the summary page's legend of the goal rows
GOAL_NOTE = ("Goal not reached: share of episodes the world did not end at its goal within the episode; time to goal: "
             "seconds from the reset until it did, over the episodes that reached it. ")  # fmt: skip


def goal_metrics(track: Track, reached: bool) -> dict[str, float]:
    """The goal metrics of one episode of a world with a goal (module docstring).

    Args:
        track: the episode's rows; its last row is the step the episode ended on.
        reached: whether the world ended the episode at its goal (the last step's ``terminated``).
    """
    elapsed = float(track.time_s[-1] - track.time_s[0])
    return {"goal_missed": 0.0 if reached else 1.0, "time_to_goal_s": elapsed if reached else math.nan}
