"""Moving obstacles: soccer robots with a ball, queueing people and free walkers.

A crowd decides a velocity for each member every step; pymunk then moves the bodies and
resolves contacts (so members push each other and our robot). The per-member logic runs
in small numba kernels over arrays, so a 14-robot soccer crowd costs a few microseconds.
All randomness comes from the world's generator, drawn as one block per step.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numba
import numpy as np
from numpy.typing import NDArray

from envs.config import CrowdConfig, WorldConfig

if TYPE_CHECKING:
    from envs.world import World

KEEPER, CHASER, WANDERER, QUEUER, WALKER = 0, 1, 2, 3, 4
ROLE_NAMES = {KEEPER: "keeper", CHASER: "chaser", WANDERER: "wanderer", QUEUER: "queuer", WALKER: "walker"}
_ARRIVE_RADIUS_M = 0.1  # a member within this distance of its target has arrived
_SLOWDOWN_S = 0.3  # members brake linearly over the last this-many seconds of travel
_TRANSIT_M = 0.5  # members farther than this from their target avoid each other
_AVOID_GAP_M = 0.4  # ... when closer than this, surface to surface
_KEEP_RIGHT_RAD = math.radians(45.0)  # the avoidance push is turned this far (pass on the right)
_RESTART_INSET_M = 0.3  # a ball off the field is put back this far inside the lines


@dataclass(frozen=True)
class Placement:
    member_xy: NDArray[np.float64]  # (N, 2)
    ball_xy: NDArray[np.float64] | None


@numba.njit(cache=True)
def seek(
    pos: NDArray[np.float64],
    targets: NDArray[np.float64],
    max_speed: NDArray[np.float64],
    held: NDArray[np.bool_],
    radii: NDArray[np.float64],
) -> NDArray[np.float64]:
    """Velocities ``(N, 2)`` that drive each member to its target, braking on arrival.

    A member in transit (farther than ``_TRANSIT_M`` from its target) also steers away from
    other members closer than ``_AVOID_GAP_M`` surface to surface; the push is turned by
    ``_KEEP_RIGHT_RAD`` so that two members meeting head-on pass each other instead of
    pressing nose to nose. Members settling into place (a queue moving up) do not avoid.
    """
    n = pos.shape[0]
    out = np.zeros((n, 2))
    cr = math.cos(_KEEP_RIGHT_RAD)
    sr = math.sin(_KEEP_RIGHT_RAD)
    for i in range(n):
        if held[i]:
            continue
        dx = targets[i, 0] - pos[i, 0]
        dy = targets[i, 1] - pos[i, 1]
        d = math.sqrt(dx * dx + dy * dy)
        if d < 1e-9:
            continue
        speed = min(max_speed[i], d / _SLOWDOWN_S)
        vx = dx / d * speed
        vy = dy / d * speed
        if d > _TRANSIT_M:
            for j in range(n):
                if j == i:
                    continue
                rx = pos[i, 0] - pos[j, 0]
                ry = pos[i, 1] - pos[j, 1]
                r = math.sqrt(rx * rx + ry * ry)
                reach = radii[i] + radii[j] + _AVOID_GAP_M
                if r < 1e-9 or r >= reach:
                    continue
                push = max_speed[i] * (reach - r) / reach / r
                vx += push * (cr * rx - sr * ry)
                vy += push * (sr * rx + cr * ry)
            v = math.sqrt(vx * vx + vy * vy)
            if v > max_speed[i]:
                vx *= max_speed[i] / v
                vy *= max_speed[i] / v
        out[i, 0] = vx
        out[i, 1] = vy
    return out


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
            if time_s >= wander_until[i] or wx * wx + wy * wy < _ARRIVE_RADIUS_M * _ARRIVE_RADIUS_M:
                due[i] = True
                n_due += 1
    return targets, due, n_due, touching


@numba.njit(cache=True)
def social_force_velocities(
    pos: NDArray[np.float64],
    vel: NDArray[np.float64],
    goals: NDArray[np.float64],
    others: NDArray[np.float64],
    seg_a: NDArray[np.float64],
    seg_b: NDArray[np.float64],
    desired_speed: float,
    relaxation_s: float,
    strength: float,
    length: float,
    dt: float,
) -> NDArray[np.float64]:
    """One explicit step of the social-force model (Helbing and Molnar, 1995).

    ``dv/dt = (v0 e - v) / tau + sum_j A exp(-d_ij / B) n_ij`` over other people and the
    robot (``others``, all positions including the walkers themselves) and walls, where
    ``d_ij`` is the centre distance (walls: distance to the segment) and ``n_ij`` the unit
    vector pointing away from the obstacle. Speeds are capped at 1.3 v0.
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
        fx = (desired_speed * ex - vel[i, 0]) / relaxation_s
        fy = (desired_speed * ey - vel[i, 1]) / relaxation_s
        for j in range(others.shape[0]):
            rx = pos[i, 0] - others[j, 0]
            ry = pos[i, 1] - others[j, 1]
            r = math.sqrt(rx * rx + ry * ry)
            if r < 1e-9:
                continue  # itself
            mag = strength * math.exp(-r / length)
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
        speed = math.sqrt(vx * vx + vy * vy)
        cap = 1.3 * desired_speed
        if speed > cap:
            vx *= cap / speed
            vy *= cap / speed
        out[i, 0] = vx
        out[i, 1] = vy
    return out


class Crowd:
    """Base crowd: members (rows ``1..N`` of the world's bodies) and maybe a ball."""

    has_ball = False

    def __init__(self, world_config: WorldConfig, radii_m: NDArray[np.float64], roles: NDArray[np.int64]) -> None:
        self.world_config = world_config
        self.config: CrowdConfig = world_config.crowd
        self.radii_m = radii_m
        self.roles = roles
        self.count = int(roles.shape[0])
        self.held = np.zeros(self.count, dtype=np.bool_)
        self.max_speed = np.full(self.count, self.config.speed_mps)

    def hold(self, index: int, flag: bool) -> None:
        self.held[index] = flag

    def reset(self, rng: np.random.Generator, robot_xy: NDArray[np.float64], robot_radius_m: float) -> Placement:
        self.held[:] = False
        return Placement(np.zeros((self.count, 2)), None)

    def velocities(self, world: World, rng: np.random.Generator) -> tuple[NDArray[np.float64], NDArray[np.float64] | None]:
        return np.zeros((self.count, 2)), None

    def ball_restart(self, ball_xy: NDArray[np.float64]) -> NDArray[np.float64] | None:
        """Where to put the ball back in play, or None (crowds without a ball: always None)."""
        return None

    # ------------------------------------------------------------------ helpers
    def _field(self, margin: float) -> tuple[float, float, float, float]:
        w, h = self.world_config.size_m
        return (margin, margin, w - margin, h - margin)

    def _free_positions(
        self, rng: np.random.Generator, count: int, radius: float, taken: list[tuple[float, float, float]]
    ) -> NDArray[np.float64]:
        """``count`` random positions in the field that overlap nothing in ``taken`` (x, y, r)."""
        x0, y0, x1, y1 = self._field(radius)
        out = np.zeros((count, 2))
        for i in range(count):
            for _ in range(1000):
                p = rng.uniform((x0, y0), (x1, y1))
                if all((p[0] - x) ** 2 + (p[1] - y) ** 2 > (r + radius + 0.05) ** 2 for x, y, r in taken):
                    break
            else:
                raise RuntimeError(
                    f"world {self.world_config.name!r}: no free space for {count} crowd members of radius {radius} m"
                )
            out[i] = p
            taken.append((float(p[0]), float(p[1]), radius))
        return out


class SoccerCrowd(Crowd):
    """A goalkeeper, ball chasers and wanderers, with a ball (Exp 2 of the candidate-set paper)."""

    def __init__(self, world_config: WorldConfig) -> None:
        cfg = world_config.crowd
        sc = cfg.soccer
        n = cfg.count
        roles = np.full(n, WANDERER, dtype=np.int64)
        start = 0
        if sc.goalkeeper and sc.keeper_posts is not None and n > 0:
            roles[0] = KEEPER
            start = 1
        if sc.ball:
            n_chasers = int(round(sc.chaser_fraction * (n - start)))
            roles[start : start + n_chasers] = CHASER
        super().__init__(world_config, np.full(n, cfg.radius_m), roles)
        self.has_ball = sc.ball
        self.soccer = sc
        posts = sc.keeper_posts or ((0.0, 0.0), (0.0, 0.0))
        self.post_a = np.asarray(posts[0], dtype=np.float64)
        self.post_b = np.asarray(posts[1], dtype=np.float64)
        w, h = world_config.size_m
        # the keeper kernel and reset() offset the keeper along the left normal of post_a -> post_b;
        # order the posts so that this normal points into the field, whatever order the config uses
        line = self.post_b - self.post_a
        to_centre = np.array([w / 2, h / 2]) - 0.5 * (self.post_a + self.post_b)
        if -line[1] * to_centre[0] + line[0] * to_centre[1] < 0:
            self.post_a, self.post_b = self.post_b, self.post_a
        # chasers attack the keeper's goal; without one, the far end of the field
        self.goal = 0.5 * (self.post_a + self.post_b) if sc.keeper_posts is not None else np.array([w / 2, h])
        self.wander = np.zeros((n, 2))
        self.wander_until = np.zeros(n)
        self.reach_m = cfg.radius_m + sc.ball_radius_m + 0.05
        self.ball_keep = 1.0 - sc.ball_decay_per_s

    def reset(self, rng: np.random.Generator, robot_xy: NDArray[np.float64], robot_radius_m: float) -> Placement:
        super().reset(rng, robot_xy, robot_radius_m)
        taken = [(float(robot_xy[0]), float(robot_xy[1]), robot_radius_m)]
        ball_xy = None
        if self.has_ball:
            ball_xy = self._free_positions(rng, 1, self.soccer.ball_radius_m, taken)[0]
        members = np.zeros((self.count, 2))
        keepers = self.roles == KEEPER
        if keepers.any():
            inward = np.array([-(self.post_b - self.post_a)[1], (self.post_b - self.post_a)[0]])
            inward /= np.linalg.norm(inward)
            members[0] = 0.5 * (self.post_a + self.post_b) + self.soccer.keeper_offset_m * inward
            taken.append((float(members[0, 0]), float(members[0, 1]), self.config.radius_m))
        others = ~keepers
        members[others] = self._free_positions(rng, int(others.sum()), self.config.radius_m, taken)
        self.wander = self._random_targets(rng, self.count)
        self.wander_until = rng.uniform(0.0, self.soccer.wander_dwell_s, self.count)
        return Placement(members, ball_xy)

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
        x0, y0, x1, y1 = self._field(self.config.radius_m)
        return rng.uniform((x0, y0), (x1, y1), size=(count, 2))

    def velocities(self, world: World, rng: np.random.Generator) -> tuple[NDArray[np.float64], NDArray[np.float64] | None]:
        pos = world.positions[world.crowd_rows]
        draws = rng.random(2)  # kick decision and direction
        ball = world.positions[world.ball_row] if self.has_ball else self.goal
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
            world.time_s,
        )
        if n_due:
            self.wander[due] = self._random_targets(rng, n_due)
            self.wander_until[due] = world.time_s + rng.uniform(0.5, self.soccer.wander_dwell_s, n_due)
            targets[due] = self.wander[due]
        member_v = seek(pos, targets, self.max_speed, self.held, self.radii_m)
        if not self.has_ball:
            return member_v, None
        # a chaser touching the ball kicks it with probability 2 % per step (about every 1.7 s at 30 Hz)
        if touching and draws[0] < 0.02:
            direction = self.goal - ball
            angle = math.atan2(direction[1], direction[0]) + (draws[1] - 0.5) * 0.5  # +-0.25 rad spread
            return member_v, self.soccer.kick_speed_mps * np.array([math.cos(angle), math.sin(angle)])
        return member_v, world.velocities[world.ball_row] * self.ball_keep**world.config.dt_s


class QueueCrowd(Crowd):
    """Two queues along the left and right walls; free walkers optionally (LIDAR paper's room).

    Every ``step_period_s`` each queue moves up one place and its head walks over to the
    end of the other queue.
    """

    def __init__(self, world_config: WorldConfig) -> None:
        cfg = world_config.crowd
        n_q = cfg.count
        n_w = cfg.walkers.count
        roles = np.array([QUEUER] * n_q + [WALKER] * n_w, dtype=np.int64)
        super().__init__(world_config, np.full(n_q + n_w, cfg.radius_m), roles)
        self.q = cfg.queues
        self.n_queuers = n_q
        self.queue_x = np.array([self.q.left_x_m, self.q.right_x_m])
        self.queue_id = np.zeros(n_q, dtype=np.int64)
        self.slot = np.zeros(n_q, dtype=np.int64)
        self.next_shift_s = self.q.step_period_s
        self.goals = np.zeros((n_w, 2))
        self.max_speed[:] = self.q.walk_speed_mps

    def reset(self, rng: np.random.Generator, robot_xy: NDArray[np.float64], robot_radius_m: float) -> Placement:
        super().reset(rng, robot_xy, robot_radius_m)
        n_q = self.n_queuers
        self.queue_id = np.arange(n_q) % 2
        self.slot = np.arange(n_q) // 2
        self.next_shift_s = float(rng.uniform(0.0, self.q.step_period_s))
        members = np.zeros((self.count, 2))
        members[:n_q] = self._slot_xy()
        taken = [(float(robot_xy[0]), float(robot_xy[1]), robot_radius_m)]
        taken += [(float(x), float(y), self.config.radius_m) for x, y in members[:n_q]]
        n_w = self.count - n_q
        members[n_q:] = self._free_positions(rng, n_w, self.config.radius_m, taken)
        self.goals = self._free_goals(rng, n_w)
        return Placement(members, None)

    def _slot_xy(self) -> NDArray[np.float64]:
        return np.stack([self.queue_x[self.queue_id], self.q.head_y_m - self.slot * self.q.spacing_m], axis=1)

    def _free_goals(self, rng: np.random.Generator, count: int) -> NDArray[np.float64]:
        x0, y0, x1, y1 = self._field(0.5)
        return rng.uniform((x0, y0), (x1, y1), size=(count, 2))

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

    def velocities(self, world: World, rng: np.random.Generator) -> tuple[NDArray[np.float64], NDArray[np.float64] | None]:
        pos = world.positions[world.crowd_rows]
        out = np.empty((self.count, 2))
        n_q = self.n_queuers
        if n_q:
            while world.time_s >= self.next_shift_s:
                self._shift_queues()
                self.next_shift_s += self.q.step_period_s
            out[:n_q] = seek(pos[:n_q], self._slot_xy(), self.max_speed[:n_q], self.held[:n_q], self.radii_m[:n_q])
        if self.count > n_q:
            w = self.config.walkers
            walker_pos = pos[n_q:]
            arrived = np.sum((walker_pos - self.goals) ** 2, axis=1) < 0.25
            if arrived.any():
                self.goals[arrived] = self._free_goals(rng, int(arrived.sum()))
            others = world.positions[: 1 + self.count]  # the robot and every person
            v = social_force_velocities(
                walker_pos,
                world.velocities[world.crowd_rows][n_q:],
                self.goals,
                others,
                world.seg_a,
                world.seg_b,
                w.desired_speed_mps,
                w.relaxation_s,
                w.repulsion_strength_mps2,
                w.repulsion_range_m,
                world.config.dt_s,
            )
            v[self.held[n_q:]] = 0.0
            out[n_q:] = v
        return out, None


def make_crowd(world_config: WorldConfig) -> Crowd:
    """The crowd model named by ``world_config.crowd.kind``."""
    kind = world_config.crowd.kind
    if kind == "soccer":
        return SoccerCrowd(world_config)
    if kind == "queues":
        return QueueCrowd(world_config)
    raise ValueError(f"world {world_config.name!r}: unknown crowd kind {kind!r}")
