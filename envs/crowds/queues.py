"""People queueing along two opposite walls (the LIDAR paper's room).

Every ``step_period_s`` each queue moves up one place and its head walks over to the end
of the other queue. A head on its way gives way to the robot (``give_way``): it sees the
robot coming and curves around it (:func:`envs.crowds.steering.give_way`), as the people
in the paper's room did, rather than walking into it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from core.schema import check
from envs.crowds.base import Commands, Crowd, PeopleConfig, Taken, register_crowd
from envs.crowds.steering import SEEK_RELAXATION_S, TRANSIT_M, give_way, seek
from envs.state import Rows, WorldState

if TYPE_CHECKING:
    from envs.config import WorldConfig

PEOPLE_FILL = (200, 120, 60)


@dataclass(frozen=True)
class QueuesConfig(PeopleConfig):
    """Two queues of ``count`` people (split evenly) along the left and right walls."""

    shape: str = "person"  # legs, a torso and a head (envs.bodies); the footprint disc collides

    left_x_m: float = 0.6  # x of the left queue's line
    right_x_m: float = 6.4  # x of the right queue's line
    head_y_m: float = 6.2  # y of the queue heads (queues extend toward smaller y)
    spacing_m: float = 0.6  # distance between people in a queue
    step_period_s: float = 5.0  # every person steps forward this often
    walk_speed_mps: float = 1.0  # speed of a head walking over to the other queue
    give_way: bool = True  # a head on its way curves around the robot
    give_way_margin_m: float = 0.3  # ... keeping this gap between its body and the robot's
    give_way_horizon_s: float = 2.0  # ... when it would come nearer within this time

    def __post_init__(self) -> None:
        super().__post_init__()
        check(self.spacing_m > 0, f"queues.spacing_m must be > 0, got {self.spacing_m}")
        check(self.step_period_s > 0, f"queues.step_period_s must be > 0, got {self.step_period_s}")
        check(self.walk_speed_mps > 0, f"queues.walk_speed_mps must be > 0, got {self.walk_speed_mps}")
        check(
            math.isfinite(self.give_way_margin_m) and self.give_way_margin_m >= 0,
            f"queues.give_way_margin_m must be finite and >= 0, got {self.give_way_margin_m}",
        )
        check(
            math.isfinite(self.give_way_horizon_s) and self.give_way_horizon_s > 0,
            f"queues.give_way_horizon_s must be finite and > 0, got {self.give_way_horizon_s}",
        )

    def top_speeds(self) -> tuple[tuple[str, float, float], ...]:
        """The people: every member seeks its place at up to ``walk_speed_mps`` (``speed_mps`` is unused)."""
        return (("people", self.walk_speed_mps, self.radius_m),)


@register_crowd("queues", QueuesConfig)
class QueueCrowd(Crowd):
    """Two queues; member ``i`` starts in queue ``i % 2`` at place ``i // 2``."""

    fill = PEOPLE_FILL

    def __init__(self, name: str, config: QueuesConfig, world: WorldConfig) -> None:
        super().__init__(name, config, world)
        self.q = config
        self.queue_x = np.array([config.left_x_m, config.right_x_m])
        self.queue_id = np.zeros(self.count, dtype=np.int64)
        self.slot = np.zeros(self.count, dtype=np.int64)
        self.next_shift_s = config.step_period_s
        self.max_speed[:] = config.walk_speed_mps

    def reset(self, rng: np.random.Generator, taken: Taken) -> NDArray[np.float64]:
        super().reset(rng, taken)
        self.queue_id = np.arange(self.count) % 2
        self.slot = np.arange(self.count) // 2
        self.next_shift_s = float(rng.uniform(0.0, self.q.step_period_s))
        members = self._slot_xy()
        taken += [(float(x), float(y), self.config.radius_m) for x, y in members]
        self.draw_seers(rng)
        return members

    def _slot_xy(self) -> NDArray[np.float64]:
        return np.stack([self.queue_x[self.queue_id], self.q.head_y_m - self.slot * self.q.spacing_m], axis=1)

    def _shift_queues(self) -> None:
        heads = self.slot == 0
        self.slot[~heads] -= 1
        for i in np.flatnonzero(heads):
            other = 1 - self.queue_id[i]
            in_other = (self.queue_id == other) & ~heads
            self.queue_id[i] = other
            self.slot[i] = int(self.slot[in_other].max()) + 1 if in_other.any() else 0
        # two heads joining the same queue (a one-person queue) must not share a slot
        for qid in (0, 1):
            members = np.flatnonzero(self.queue_id == qid)
            order = members[np.argsort(self.slot[members], kind="stable")]
            self.slot[order] = np.arange(order.size)

    def commands(self, state: WorldState, others: Rows, rng: np.random.Generator) -> Commands:
        while state.time_s >= self.next_shift_s:
            self._shift_queues()
            self.next_shift_s += self.q.step_period_s
        pos = state.positions[self.member_rows]
        targets = self._slot_xy()
        want = seek(pos, targets, self.max_speed, self.held, self.radii_m)
        if self.q.give_way:
            walking = np.sum((targets - pos) ** 2, axis=1) > TRANSIT_M**2
            if walking.any():
                want = give_way(
                    pos,
                    want,
                    self.radii_m,
                    walking & ~self.held,
                    state.positions[0],
                    state.velocities[0],
                    state.robot_radius_m,
                    self.q.give_way_margin_m,
                    self.q.give_way_horizon_s,
                )
        self.react_to_robot(state, want, slice(0, self.count), self.max_speed, SEEK_RELAXATION_S)
        return Commands(want)
