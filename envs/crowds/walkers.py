"""Free-walking pedestrians with social-force avoidance (Helbing and Molnar style).

Each walker heads for a random goal in the field and picks a new one on arrival; other
people, the robot and the walls repel it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numba
import numpy as np
from numpy.typing import NDArray

from core.schema import check
from envs.crowds.base import Commands, Crowd, PeopleConfig, Taken, register_crowd
from envs.crowds.queues import PEOPLE_FILL
from envs.crowds.steering import cap_speed
from envs.state import Rows, WorldState

if TYPE_CHECKING:
    from envs.config import WorldConfig


#: the social force caps a walker's speed at this multiple of its desired speed
SPEED_CAP = 1.3


@dataclass(frozen=True)
class WalkersConfig(PeopleConfig):
    """Free walkers: ``count`` people with social-force avoidance."""

    shape: str = "person"  # legs, a torso and a head (envs.bodies); the footprint disc collides

    desired_speed_mps: float = 1.0
    relaxation_s: float = 0.5  # time to reach the desired velocity
    repulsion_strength_mps2: float = 2.0  # magnitude of the exponential repulsion
    repulsion_range_m: float = 0.3  # length scale of the repulsion

    def __post_init__(self) -> None:
        super().__post_init__()
        check(self.desired_speed_mps > 0, f"walkers.desired_speed_mps must be > 0, got {self.desired_speed_mps}")
        check(self.relaxation_s > 0, f"walkers.relaxation_s must be > 0, got {self.relaxation_s}")
        check(self.repulsion_range_m > 0, f"walkers.repulsion_range_m must be > 0, got {self.repulsion_range_m}")

    def top_speeds(self) -> tuple[tuple[str, float, float], ...]:
        """The walkers: the social force caps their speed at ``SPEED_CAP`` times ``desired_speed_mps``."""
        return (("walkers", SPEED_CAP * self.desired_speed_mps, self.radius_m),)


@numba.njit(cache=True)
def social_force_velocities(
    pos: NDArray[np.float64],
    vel: NDArray[np.float64],
    goals: NDArray[np.float64],
    others: NDArray[np.float64],
    seg_a: NDArray[np.float64],
    seg_b: NDArray[np.float64],
    desired_speed: NDArray[np.float64],
    relaxation_s: float,
    strength: float,
    length: float,
    dt: float,
    other_gain: NDArray[np.float64],
) -> NDArray[np.float64]:
    """One explicit step of the social-force model (Helbing and Molnar, 1995).

    ``dv/dt = (v0_i e - v) / tau + sum_j g_j A exp(-d_ij / B) n_ij`` over other people and the
    robot (``others``, all positions including the walkers themselves) and walls (``g = 1``),
    where ``d_ij`` is the centre distance (walls: distance to the segment) and ``n_ij`` the
    unit vector pointing away from the obstacle. Speeds are capped at 1.3 v0_i.

    Args:
        pos, vel, goals: ``(N, 2)`` the walkers' positions, velocities and goals.
        others: ``(M, 2)`` positions of everyone who repels them.
        seg_a, seg_b: ``(S, 2)`` wall segments.
        desired_speed: ``(N,)`` each walker's desired speed v0_i.
        relaxation_s, strength, length: tau, A and B.
        dt: the time step.
        other_gain: ``(M,)`` each other's repulsion as a multiple of ``strength`` (ones: all
            alike; a larger value for the robot makes people keep clear of it).
    """
    n = pos.shape[0]
    out = np.empty((n, 2))
    for i in range(n):
        ex = goals[i, 0] - pos[i, 0]
        ey = goals[i, 1] - pos[i, 1]
        d = math.sqrt(ex * ex + ey * ey)
        if d > 1e-9:
            ex /= d
            ey /= d
        fx = (desired_speed[i] * ex - vel[i, 0]) / relaxation_s
        fy = (desired_speed[i] * ey - vel[i, 1]) / relaxation_s
        for j in range(others.shape[0]):
            rx = pos[i, 0] - others[j, 0]
            ry = pos[i, 1] - others[j, 1]
            r = math.sqrt(rx * rx + ry * ry)
            if r < 1e-9:
                continue  # itself
            mag = strength * other_gain[j] * math.exp(-r / length)
            fx += mag * rx / r
            fy += mag * ry / r
        for s in range(seg_a.shape[0]):
            ax = seg_a[s, 0]
            ay = seg_a[s, 1]
            wx = seg_b[s, 0] - ax
            wy = seg_b[s, 1] - ay
            l2 = wx * wx + wy * wy
            t = 0.0
            if l2 > 0:
                t = min(1.0, max(0.0, ((pos[i, 0] - ax) * wx + (pos[i, 1] - ay) * wy) / l2))
            rx = pos[i, 0] - (ax + t * wx)
            ry = pos[i, 1] - (ay + t * wy)
            r = math.sqrt(rx * rx + ry * ry)
            if r < 1e-9:
                continue
            mag = strength * math.exp(-r / length)
            fx += mag * rx / r
            fy += mag * ry / r
        vx = vel[i, 0] + dt * fx
        vy = vel[i, 1] + dt * fy
        vx, vy, _ = cap_speed(vx, vy, SPEED_CAP * desired_speed[i])
        out[i, 0] = vx
        out[i, 1] = vy
    return out


@register_crowd("walkers", WalkersConfig)
class WalkerCrowd(Crowd):
    """Walkers placed at random free spots, each with a random goal."""

    fill = PEOPLE_FILL

    def __init__(self, name: str, config: WalkersConfig, world: WorldConfig) -> None:
        super().__init__(name, config, world)
        self.w = config
        self.goals = np.zeros((self.count, 2))
        self.dt_s = world.dt_s
        self.desired_speed = np.full(self.count, config.desired_speed_mps)

    def _free_goals(self, rng: np.random.Generator, count: int) -> NDArray[np.float64]:
        x0, y0, x1, y1 = self.field_box(0.5)
        return rng.uniform((x0, y0), (x1, y1), size=(count, 2))

    def reset(self, rng: np.random.Generator, taken: Taken) -> NDArray[np.float64]:
        super().reset(rng, taken)
        members = self.free_positions(rng, self.count, self.config.radius_m, taken)
        self.goals = self._free_goals(rng, self.count)
        self.draw_seers(rng)
        return members

    def commands(self, state: WorldState, others: Rows, rng: np.random.Generator) -> Commands:
        w = self.w
        pos = state.positions[self.member_rows]
        arrived = np.sum((pos - self.goals) ** 2, axis=1) < 0.25
        if arrived.any():
            self.goals[arrived] = self._free_goals(rng, int(arrived.sum()))
        others_xy = state.positions[others]  # the robot and every person, walkers included
        v = social_force_velocities(
            pos,
            state.velocities[self.member_rows],
            self.goals,
            others_xy,
            state.seg_a,
            state.seg_b,
            self.desired_speed,
            w.relaxation_s,
            w.repulsion_strength_mps2,
            w.repulsion_range_m,
            self.dt_s,
            np.ones(others_xy.shape[0]),  # everyone repels alike
        )
        self.react_to_robot(state, v, slice(0, self.count), SPEED_CAP * self.desired_speed, self.dt_s)
        v[self.held] = 0.0
        return Commands(v)
