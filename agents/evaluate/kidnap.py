"""The kidnapping study of ``crowdloc eval --kidnap-at-s S``: the robot is carried away mid-episode.

At the first step at or after ``at_s`` the robot is teleported to a random free pose at least
``min_distance_m`` from where it stood (:func:`agents.experiments.scenarios.kidnap`; odometry does not see
it, the localizer is not told): by default anywhere in the arena with a random heading; with
``max_distance_m`` at most that far, and with ``keep_heading`` a pure translation (a
kidnap of 2-5 m: ``--kidnap-m 2 --kidnap-max-m 5 --kidnap-keep-heading``). From the jump on, over ``window_s``:

- ``recovered``: 1 if the localizer is back for good within the window: it claims a pose
  within ``recover_m`` of the truth and, from then to the end of the window, no claimed pose
  is more than ``wrong_m`` off; else 0 (passing near the truth on the way elsewhere is no recovery);
- ``recovery_s``: the time from the jump to that good pose (NaN when not recovered: the
  tables average the recovered episodes, with their count);
- ``wrong_valid_s``: seconds of the window in which it claimed a pose more than ``wrong_m``
  off (a confident wrong pose: what a localizer that knows it is lost avoids);
- ``lost_s``: seconds of the window in which it claimed no pose (the honest answer while it
  does not know where it is).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from agents.evaluate.plugins import MetricInfo, Track
from core.schema import check

#: the kidnapping metrics, after the core ones in the tables
KIDNAP_METRICS: tuple[MetricInfo, ...] = (
    MetricInfo("recovered", "recovered after the kidnap", "{:.2f}"),
    MetricInfo("recovery_s", "time to recover [s] (recovered episodes)", "{:.2f}"),
    MetricInfo("wrong_valid_s", "confident wrong pose after the kidnap [s]", "{:.2f}"),
    MetricInfo("lost_s", "no pose claimed after the kidnap [s]", "{:.2f}"),
)
#: salts the kidnap's generator: the jump differs from the env's and the policy's draws for the same seed
KIDNAP_SALT = 0x4B1D


@dataclass(frozen=True)
class Kidnap:
    """When and how far the robot is carried away, and what counts as recovered.

    Attributes:
        at_s: time of the jump after the reset (s).
        min_distance_m: the robot lands at least this far from where it stood.
        max_distance_m: ... and at most this far (inf: anywhere in the arena).
        keep_heading: the robot keeps its heading (a pure translation); False: a random heading.
        recover_m: a claimed pose this close to the truth is a recovery.
        wrong_m: a claimed pose farther off than this is a confident wrong pose.
        window_s: how long after the jump recovery is looked for.
    """

    at_s: float = 10.0
    min_distance_m: float = 2.0
    recover_m: float = 0.2
    wrong_m: float = 1.0
    window_s: float = 30.0
    max_distance_m: float = math.inf
    keep_heading: bool = False

    def __post_init__(self) -> None:
        for name in ("at_s", "min_distance_m"):
            value = getattr(self, name)
            check(math.isfinite(value) and value >= 0.0, f"kidnap.{name} must be a finite number >= 0, got {value!r}")
        for name in ("recover_m", "wrong_m", "window_s"):
            value = getattr(self, name)
            check(math.isfinite(value) and value > 0.0, f"kidnap.{name} must be a finite number > 0, got {value!r}")
        check(
            self.max_distance_m > self.min_distance_m,  # false for NaN
            f"kidnap.max_distance_m must be a number above min_distance_m {self.min_distance_m}, got {self.max_distance_m!r}",
        )
        check(isinstance(self.keep_heading, bool), f"kidnap.keep_heading must be true or false, got {self.keep_heading!r}")
        check(self.wrong_m >= self.recover_m, f"kidnap.wrong_m {self.wrong_m} must be at least recover_m {self.recover_m}")

    @property
    def ends_s(self) -> float:
        """When the recovery window closes (s after the reset): an episode must last this long."""
        return self.at_s + self.window_s


def kidnap_metrics(track: Track, kidnap: Kidnap, jump_index: int | None) -> dict[str, float]:
    """The kidnapping metrics (module docstring) of one episode whose robot jumped before row ``jump_index``.

    ``jump_index`` is the first row of ``track`` recorded after the jump; None when the episode
    ended before it (every metric NaN).
    """
    if jump_index is None:
        return dict.fromkeys((m.key for m in KIDNAP_METRICS), math.nan)
    t = track.time_s
    jump_s = float(t[jump_index - 1]) if jump_index > 0 else float(t[0])
    rows = np.flatnonzero((np.arange(t.size) >= jump_index) & (t <= jump_s + kidnap.window_s + 1e-9))
    dt = float(np.median(np.diff(t))) if t.size > 1 else 0.0
    error = track.position_errors[rows]  # NaN where no pose is claimed
    valid = track.valid[rows]
    wrong = valid & (error > kidnap.wrong_m)
    after = int(np.flatnonzero(wrong)[-1]) + 1 if wrong.any() else 0  # past the last confident wrong pose
    good = np.flatnonzero(valid & (error < kidnap.recover_m) & (np.arange(rows.size) >= after))
    return {
        "recovered": float(good.size > 0),
        "recovery_s": float(t[rows[good[0]]] - jump_s) if good.size else math.nan,
        "wrong_valid_s": float(np.sum(wrong)) * dt,
        "lost_s": float(np.sum(~valid)) * dt,
    }
