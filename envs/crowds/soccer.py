"""Soccer robots and their ball: a goalkeeper, ball chasers and wanderers (candidate-set paper, Exp 2).

The crowd owns the ball: it is one of the crowd's bodies (after the members), its velocity
is set every step (rolling friction, kicks), and a ball wholly off the field is put back in
play as a referee would. All randomness comes from the world's generator, one block per step.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numba
import numpy as np
from numpy.typing import NDArray

from core.schema import check, check_ranges
from envs.crowds.base import BodySpec, Commands, Crowd, CrowdConfig, Taken, register_crowd
from envs.crowds.steering import ARRIVE_RADIUS_M, seek
from envs.state import Rows, WorldState

if TYPE_CHECKING:
    from envs.config import WorldConfig

KEEPER, CHASER, WANDERER = 0, 1, 2
ROLE_NAMES = {KEEPER: "keeper", CHASER: "chaser", WANDERER: "wanderer"}
_RESTART_INSET_M = 0.3  # a ball off the field is put back this far inside the lines
BALL_COLOR = (255, 120, 0)


@dataclass(frozen=True)
class SoccerConfig(CrowdConfig):
    """Other soccer robots and a ball (candidate-set paper, Exp 2)."""

    height_m: float = 0.8  # RoboCup middle-size robots are at most 80 cm tall
    ball: bool = True
    ball_radius_m: float = 0.11
    ball_mass_kg: float = 0.45
    ball_decay_per_s: float = 0.6  # fraction of ball speed lost per second (rolling friction)
    ball_occludes: bool = False  # the omni camera sits above ball height
    goalkeeper: bool = True  # the first robot keeps the goal between keeper_posts
    keeper_posts: tuple[tuple[float, float], tuple[float, float]] | None = None
    keeper_offset_m: float = 0.4  # distance in front of the goal line
    chaser_fraction: float = 0.5  # share of the remaining robots that go for the ball
    kick_speed_mps: float = 3.0  # ball speed after a chaser kicks it
    wander_dwell_s: float = 3.0  # wanderers pick a new target after at most this long

    def __post_init__(self) -> None:
        super().__post_init__()
        check(0 <= self.chaser_fraction <= 1, f"soccer.chaser_fraction must be in [0, 1], got {self.chaser_fraction}")
        check(self.ball_radius_m > 0, f"soccer.ball_radius_m must be > 0, got {self.ball_radius_m}")
        check_ranges(self, "soccer", positive=("ball_mass_kg",))  # (a pymunk body: a mass <= 0 aborts the process)
        check(0 <= self.ball_decay_per_s < 1, f"soccer.ball_decay_per_s must be in [0, 1), got {self.ball_decay_per_s}")
        check(self.kick_speed_mps > 0, f"soccer.kick_speed_mps must be > 0, got {self.kick_speed_mps}")

    def top_speeds(self) -> tuple[tuple[str, float, float], ...]:
        """The robots (``speed_mps``) and, with ``ball``, the ball: a kick sets it to ``kick_speed_mps``, then it slows."""
        robots = ("robots", self.speed_mps, self.radius_m)
        return (robots, ("ball", self.kick_speed_mps, self.ball_radius_m)) if self.ball else (robots,)


@numba.njit(cache=True)
def soccer_targets(
    pos: NDArray[np.float64],
    roles: NDArray[np.int64],
    wander: NDArray[np.float64],
    ball: NDArray[np.float64],
    goal: NDArray[np.float64],
    post_a: NDArray[np.float64],
    post_b: NDArray[np.float64],
    keeper_offset: float,
    reach: float,
    wander_until: NDArray[np.float64],
    time_s: float,
) -> tuple[NDArray[np.float64], NDArray[np.bool_], int, bool]:
    """Soccer-role targets ``(N, 2)``, wanderers due a new target (mask and count), any chaser on the ball.

    Keeper: the point on its goal line (``post_a``-``post_b``, shifted ``keeper_offset``
    into the field) whose along-line coordinate equals the ball's, clipped between the
    posts (Exp 2: x = ball x, 1.5 m <= x <= 3.5 m). Chaser: behind the ball on the line
    from ``goal`` through the ball, then through the ball toward the goal (dribbling).
    Wanderer: its wander target; it is due a new one on arrival or after ``wander_until``.
    """
    n = pos.shape[0]
    targets = np.empty((n, 2))
    touching = False
    due = np.zeros(n, dtype=np.bool_)
    n_due = 0
    ux = post_b[0] - post_a[0]
    uy = post_b[1] - post_a[1]
    length2 = ux * ux + uy * uy
    # inward normal: from the goal line toward the field centre (the ball's side on average)
    nx, ny = -uy, ux
    norm = math.sqrt(nx * nx + ny * ny)
    if norm > 0:
        nx /= norm
        ny /= norm
    gx = goal[0] - ball[0]
    gy = goal[1] - ball[1]
    gd = math.sqrt(gx * gx + gy * gy)
    if gd > 1e-9:
        gx /= gd
        gy /= gd
    for i in range(n):
        role = roles[i]
        if role == 0:  # keeper
            s = 0.0
            if length2 > 0:
                s = ((ball[0] - post_a[0]) * ux + (ball[1] - post_a[1]) * uy) / length2
            s = min(1.0, max(0.0, s))
            targets[i, 0] = post_a[0] + s * ux + keeper_offset * nx
            targets[i, 1] = post_a[1] + s * uy + keeper_offset * ny
        elif role == 1:  # chaser
            bx = ball[0] - pos[i, 0]
            by = ball[1] - pos[i, 1]
            dist = math.sqrt(bx * bx + by * by)
            behind = (bx * gx + by * gy) > 0.5 * dist  # the ball lies between us and the goal
            if dist < reach and behind:
                touching = True
                targets[i, 0] = ball[0] + gx * reach
                targets[i, 1] = ball[1] + gy * reach
            else:
                targets[i, 0] = ball[0] - gx * reach
                targets[i, 1] = ball[1] - gy * reach
        else:
            targets[i, 0] = wander[i, 0]
            targets[i, 1] = wander[i, 1]
            wx = wander[i, 0] - pos[i, 0]
            wy = wander[i, 1] - pos[i, 1]
            if time_s >= wander_until[i] or wx * wx + wy * wy < ARRIVE_RADIUS_M * ARRIVE_RADIUS_M:
                due[i] = True
                n_due += 1
    return targets, due, n_due, touching


@register_crowd("soccer", SoccerConfig)
class SoccerCrowd(Crowd):
    """A goalkeeper, ball chasers and wanderers, with a ball (Exp 2 of the candidate-set paper).

    Public control for scripted plays: :attr:`ball_row`, :attr:`goal`, :meth:`keeper_index`,
    :meth:`send` (a member's next target).
    """

    fill = (30, 30, 70)

    def __init__(self, name: str, config: SoccerConfig, world: WorldConfig) -> None:
        super().__init__(name, config, world)
        sc = self.soccer = config
        n = self.count
        roles = np.full(n, WANDERER, dtype=np.int64)
        start = 0
        if sc.goalkeeper and sc.keeper_posts is not None and n > 0:
            roles[0] = KEEPER
            start = 1
        if sc.ball:
            n_chasers = int(round(sc.chaser_fraction * (n - start)))
            roles[start : start + n_chasers] = CHASER
        self.roles = roles
        self.has_ball = sc.ball
        posts = sc.keeper_posts or ((0.0, 0.0), (0.0, 0.0))
        self.post_a = np.asarray(posts[0], dtype=np.float64)
        self.post_b = np.asarray(posts[1], dtype=np.float64)
        w, h = world.size_m
        # the keeper kernel and reset() offset the keeper along the left normal of post_a -> post_b;
        # order the posts so that this normal points into the field, whatever order the config uses
        line = self.post_b - self.post_a
        to_centre = np.array([w / 2, h / 2]) - 0.5 * (self.post_a + self.post_b)
        if -line[1] * to_centre[0] + line[0] * to_centre[1] < 0:
            self.post_a, self.post_b = self.post_b, self.post_a
        #: where chasers attack: the keeper's goal; without one, the far end of the field
        self.goal = 0.5 * (self.post_a + self.post_b) if sc.keeper_posts is not None else np.array([w / 2, h])
        self.wander = np.zeros((n, 2))
        self.wander_until = np.zeros(n)
        self.reach_m = config.radius_m + sc.ball_radius_m + 0.05
        self.ball_keep = 1.0 - sc.ball_decay_per_s
        self.dt_s = world.dt_s
        self.ball_row = -1  # set by attach()

    def bodies(self) -> list[BodySpec]:
        members = super().bodies()
        if not self.has_ball:
            return members
        sc = self.soccer
        return [*members, BodySpec("ball", sc.ball_radius_m, sc.ball_mass_kg, sc.ball_occludes, 0.3, 0.7, shape="ball")]

    def attach(self, rows: NDArray[np.int64]) -> None:
        super().attach(rows)
        #: the ball's body row in the world, -1 without a ball
        self.ball_row = int(self.rows[self.count]) if self.has_ball else -1

    def keeper_index(self) -> int | None:
        """The goalkeeper's member index, or None."""
        return 0 if self.count and int(self.roles[0]) == KEEPER else None

    def send(self, index: int, target_xy: NDArray[np.float64], until_s: float | None = None) -> None:
        """Scripted control: wanderer ``index`` heads for ``target_xy`` (until ``until_s``; None: its current deadline)."""
        self.check_member(index)
        self.wander[index] = target_xy
        if until_s is not None:
            self.wander_until[index] = until_s

    def reset(self, rng: np.random.Generator, taken: Taken) -> NDArray[np.float64]:
        super().reset(rng, taken)
        out = np.zeros((len(self.bodies()), 2))
        if self.has_ball:
            out[self.count] = self.free_positions(rng, 1, self.soccer.ball_radius_m, taken)[0]
        members = out[: self.count]
        keepers = self.roles == KEEPER
        if keepers.any():
            inward = np.array([-(self.post_b - self.post_a)[1], (self.post_b - self.post_a)[0]])
            inward /= np.linalg.norm(inward)
            members[0] = 0.5 * (self.post_a + self.post_b) + self.soccer.keeper_offset_m * inward
            taken.append((float(members[0, 0]), float(members[0, 1]), self.config.radius_m))
        others = ~keepers
        members[others] = self.free_positions(rng, int(others.sum()), self.config.radius_m, taken)
        self.wander = self._random_targets(rng, self.count)
        self.wander_until = rng.uniform(0.0, self.soccer.wander_dwell_s, self.count)
        return out

    def ball_restart(self, ball_xy: NDArray[np.float64]) -> NDArray[np.float64] | None:
        """Where to put the ball back in play once it is wholly off the field, else None.

        As a referee would: at the nearest point ``_RESTART_INSET_M`` inside the lines.
        """
        w, h = self.world_config.size_m
        r = self.soccer.ball_radius_m
        x, y = float(ball_xy[0]), float(ball_xy[1])
        if -r <= x <= w + r and -r <= y <= h + r:
            return None
        return np.array(
            [min(max(x, _RESTART_INSET_M), w - _RESTART_INSET_M), min(max(y, _RESTART_INSET_M), h - _RESTART_INSET_M)]
        )

    def _random_targets(self, rng: np.random.Generator, count: int) -> NDArray[np.float64]:
        x0, y0, x1, y1 = self.field_box(self.config.radius_m)
        return rng.uniform((x0, y0), (x1, y1), size=(count, 2))

    def commands(self, state: WorldState, others: Rows, rng: np.random.Generator) -> Commands:
        pos = state.positions[self.member_rows]
        draws = rng.random(2)  # kick decision and direction
        ball_row = self.ball_row
        ball = state.positions[ball_row] if self.has_ball else self.goal
        targets, due, n_due, touching = soccer_targets(
            pos,
            self.roles,
            self.wander,
            ball,
            self.goal,
            self.post_a,
            self.post_b,
            self.soccer.keeper_offset_m,
            self.reach_m,
            self.wander_until,
            state.time_s,
        )
        if n_due:
            self.wander[due] = self._random_targets(rng, n_due)
            self.wander_until[due] = state.time_s + rng.uniform(0.5, self.soccer.wander_dwell_s, n_due)
            targets[due] = self.wander[due]
        member_v = seek(pos, targets, self.max_speed, self.held, self.radii_m)
        if not self.has_ball:
            return Commands(member_v)
        # a chaser touching the ball kicks it with probability 2 % per step (about every 1.7 s at 30 Hz)
        if touching and draws[0] < 0.02:
            direction = self.goal - ball
            angle = math.atan2(direction[1], direction[0]) + (draws[1] - 0.5) * 0.5  # +-0.25 rad spread
            ball_v = self.soccer.kick_speed_mps * np.array([math.cos(angle), math.sin(angle)])
        else:
            ball_v = state.velocities[ball_row] * self.ball_keep**self.dt_s
        restart = self.ball_restart(state.positions[ball_row])
        return Commands(member_v, ball_v, () if restart is None else ((self.count, restart),))

    def draw(self, canvas: Any, state: WorldState) -> None:
        super().draw(canvas, state)
        if self.has_ball:
            bx, by = state.positions[self.ball_row]
            canvas.circle(bx, by, state.radii_m[self.ball_row], BALL_COLOR, 0)
