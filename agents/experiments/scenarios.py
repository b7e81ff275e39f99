"""Scripted scenario drivers: what moves the robot (and the ball) in the paper reproductions.

A driver is the robot's *own control*, not its localizer. Two kinds:

- :class:`OpenLoopDriver` replays a fixed list of ``(v, omega, steps)`` commands and never
  looks at the world (Exp 1 of the candidate-set paper: a closed polygon with straight lines
  and turns in place; without contacts the simulated body moves exactly as commanded). The
  commands themselves (:func:`~agents.policies.paths.polygon_commands`) are the policies'
  open-loop paths, shared with the ``patrol`` policy.
- Closed-loop drivers (:class:`SoccerDriver`, :class:`PatrolDriver`, :class:`ShoveDriver`)
  read the world's *true* state to decide their commands and may move the ball or a crowd
  member (a kick, a shove). They play the part of the paper's field robot's own controller
  and of the referee. Their knowledge never reaches a localizer: localizers are fed only
  from the recorded observation leaves (:mod:`agents.experiments.replay`).

Every driver has ``reset(env)`` (called right after ``env.reset``) and ``act(env)`` (the
next action in ``[-1, 1]^2``), with ``env`` the unwrapped :class:`envs.LocalizationEnv`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING, Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from agents.policies.paths import EXP1_VERTICES, Command, command_actions, polygon_commands, square_vertices
from core.geometry import wrap_angle
from envs.crowds import SoccerCrowd

if TYPE_CHECKING:
    from envs.localization_env import LocalizationEnv
    from envs.world import World

Action = NDArray[np.float32]


class Driver(Protocol):
    """What the recorder needs from a scenario driver."""

    def reset(self, env: LocalizationEnv) -> None:
        """Set the scenario up after ``env.reset`` (may place the ball or crowd members)."""

    def act(self, env: LocalizationEnv) -> Action:
        """The next action ``(2,)`` float32 in ``[-1, 1]``."""

    @property
    def done(self) -> bool:
        """Whether the scenario has ended."""


class OpenLoopDriver:
    """Plays a list of :class:`Command` and then stops; never reads the world.

    Args:
        commands: the commands in order.
        max_speed_mps, max_turn_rate_rps: the env's action scaling.
    """

    def __init__(self, commands: Sequence[Command], max_speed_mps: float, max_turn_rate_rps: float) -> None:
        self._actions = list(command_actions(commands, max_speed_mps, max_turn_rate_rps))
        self._next = 0

    @property
    def total_steps(self) -> int:
        return len(self._actions)

    def reset(self, env: LocalizationEnv) -> None:
        del env
        self._next = 0

    def act(self, env: LocalizationEnv) -> Action:
        del env
        if self.done:
            raise RuntimeError("OpenLoopDriver: no commands left")
        a = self._actions[self._next]
        self._next += 1
        return a.copy()

    @property
    def done(self) -> bool:
        return self._next >= len(self._actions)


def exp1_driver(env: LocalizationEnv, speed_mps: float = 0.5, turn_rate_rps: float = 1.0) -> OpenLoopDriver:
    """The Exp 1 patrol a-b-c-d-e-f-g-h-a of :data:`EXP1_VERTICES`, open loop, from the world's start pose."""
    start = env.config.robot.start_pose
    if start is None:
        raise ValueError("exp1_driver needs a world with a fixed robot start_pose")
    commands = polygon_commands(
        list(EXP1_VERTICES.values()), start[2], speed_mps=speed_mps, turn_rate_rps=turn_rate_rps, dt_s=env.config.dt_s
    )
    return OpenLoopDriver(commands, env.max_speed_mps, env.max_turn_rate_rps)


def square_driver(
    env: LocalizationEnv,
    *,
    center_xy: tuple[float, float],
    side_m: float,
    laps: int,
    speed_mps: float,
    turn_rate_rps: float,
) -> OpenLoopDriver:
    """``laps`` open-loop laps of :func:`square_vertices`: straight sides, 90 deg turns in place.

    The robot must start on the lower-left corner facing +x (reset option ``robot_pose``);
    every lap ends there with that heading (the far-point paper's square path).
    """
    if laps < 1:
        raise ValueError(f"square_driver: laps must be >= 1, got {laps!r}")
    lap = polygon_commands(
        square_vertices(center_xy, side_m), 0.0, speed_mps=speed_mps, turn_rate_rps=turn_rate_rps, dt_s=env.config.dt_s
    )
    return OpenLoopDriver(lap * laps, env.max_speed_mps, env.max_turn_rate_rps)


# ---------------------------------------------------------------------------------- closed loop


def steer(
    pose: NDArray[np.float64],
    target_xy: NDArray[np.float64],
    speed_mps: float,
    env: LocalizationEnv,
    *,
    gain: float = 4.0,
    brake_m: float = 0.4,
) -> Action:
    """Differential-drive go-to-point: turn toward the target, drive when roughly facing it.

    Args:
        pose: ``(3,)`` the robot's pose.
        target_xy: ``(2,)`` where to go.
        speed_mps: cruise speed; reduced within ``brake_m`` of the target and when misaligned
            (``cos^3`` of the heading error, no forward motion beyond 90 degrees).
        env: for the action scaling.
        gain: turn-rate gain per radian of heading error.
        brake_m: braking distance.
    """
    d = np.asarray(target_xy, dtype=np.float64) - pose[:2]
    dist = float(np.hypot(*d))
    err = float(wrap_angle(math.atan2(d[1], d[0]) - pose[2])) if dist > 1e-6 else 0.0
    omega = float(np.clip(gain * err, -env.max_turn_rate_rps, env.max_turn_rate_rps))
    v = speed_mps * min(1.0, dist / brake_m) * max(0.0, math.cos(err)) ** 3
    return _action(env, v, omega)


def turn_toward(pose: NDArray[np.float64], direction_rad: float, env: LocalizationEnv, gain: float = 4.0) -> Action:
    """Turn in place toward a world direction."""
    err = float(wrap_angle(direction_rad - pose[2]))
    return _action(env, 0.0, float(np.clip(gain * err, -env.max_turn_rate_rps, env.max_turn_rate_rps)))


def _action(env: LocalizationEnv, v_mps: float, omega_rps: float) -> Action:
    a = np.array([v_mps / env.max_speed_mps, omega_rps / env.max_turn_rate_rps])
    return np.clip(a, -1.0, 1.0).astype(np.float32)


def _unit(v: NDArray[np.float64]) -> NDArray[np.float64]:
    n = float(np.hypot(*v))
    return v / n if n > 1e-9 else np.zeros(2)


def soccer_crowd(world: World) -> SoccerCrowd:
    """The world's soccer crowd (the one with the ball, if several), or a ValueError."""
    crowds = [c for c in world.crowds.values() if isinstance(c, SoccerCrowd)]
    if not crowds:
        raise ValueError(f"world {world.config.name!r} has no soccer crowd")
    return next((c for c in crowds if c.has_ball), crowds[0])


def set_ball(world: World, xy: ArrayLike, velocity: ArrayLike = (0.0, 0.0)) -> None:
    """Put the ball at ``xy`` with ``velocity`` (scripted kicks, dribbling, a referee's restart)."""
    row = soccer_crowd(world).ball_row
    if row < 0:
        raise ValueError("set_ball: this world has no ball")
    p, v = np.asarray(xy, dtype=np.float64), np.asarray(velocity, dtype=np.float64)
    world.place_body(row, (float(p[0]), float(p[1])), (float(v[0]), float(v[1])))


class SoccerDriver:
    """Exp 2's field robot and referee: the keeper kicks the ball out, we chase, dribble and shoot.

    One *play*: the ball is placed in front of the keeper (or the goal mouth without one),
    which kicks it toward our half after ``kickoff_s`` (speed and direction from the driver's
    own seeded generator); our robot goes behind the ball, takes it (dribbling holds the ball
    just in front of the robot, as a dribbler would), drives it toward the keeper's goal, turns
    toward the open side of the goal and shoots (ball speed ``shot_speed_mps``); ``after_shot_s``
    later the referee starts the next play. Between plays the robot heads for a waiting point.
    The driver reads true poses (it is the robot's own control, not its localizer).

    Args:
        seed: seed of the driver's generator (kick directions, waiting points).
        chase_speed_mps: top speed when chasing (paper: 1.753 m/s maximum).
        dribble_speed_mps: speed while dribbling.
        shoot_line_y_m: the robot shoots once it has dribbled past this line.
        kick_out_speed_mps: range of the keeper's kick-out speed.
        kick_out_spread_rad: the kick-out direction is uniform within this of -y (toward our half).
    """

    KICKOFF, CHASE, DRIBBLE, AIM, AFTER_SHOT = range(5)

    def __init__(
        self,
        seed: int,
        *,
        chase_speed_mps: float = 1.75,
        dribble_speed_mps: float = 1.4,
        shoot_line_y_m: float = 3.2,
        kickoff_s: float = 0.5,
        after_shot_s: float = 1.5,
        kick_out_speed_mps: tuple[float, float] = (1.5, 2.5),
        kick_out_spread_rad: float = 0.9,
        shot_speed_mps: float = 3.0,
        max_dribble_s: float = 5.0,
    ) -> None:
        self.seed = seed
        self.chase_speed_mps = chase_speed_mps
        self.dribble_speed_mps = dribble_speed_mps
        self.shoot_line_y_m = shoot_line_y_m
        self.kickoff_s = kickoff_s
        self.after_shot_s = after_shot_s
        self.kick_out_speed_mps = kick_out_speed_mps
        self.kick_out_spread_rad = kick_out_spread_rad
        self.shot_speed_mps = shot_speed_mps
        self.max_dribble_s = max_dribble_s
        self.rng = np.random.default_rng(seed)
        self.phase = self.KICKOFF
        self._phase_start_s = 0.0
        self._wait_xy = np.array([2.5, 2.0])
        self._aim_xy = np.array([2.5, 5.0])
        self.plays = 0
        self.shots = 0

    @property
    def done(self) -> bool:
        return False

    def reset(self, env: LocalizationEnv) -> None:
        self.rng = np.random.default_rng(self.seed)
        self.plays = self.shots = 0
        self._start_play(env)

    # -------------------------------------------------------------------- geometry helpers
    def _field(self, env: LocalizationEnv) -> tuple[float, float]:
        w, h = env.config.size_m
        return float(w), float(h)

    def _clip(self, env: LocalizationEnv, xy: NDArray[np.float64], margin: float = 0.35) -> NDArray[np.float64]:
        w, h = self._field(env)
        return np.clip(xy, [margin, margin], [w - margin, h - margin])

    def _keeper_xy(self, env: LocalizationEnv) -> NDArray[np.float64] | None:
        crowd = soccer_crowd(env.world)
        keeper = crowd.keeper_index()
        return None if keeper is None else np.asarray(env.world.positions[crowd.rows[keeper]], dtype=np.float64)

    def _goal_xy(self, env: LocalizationEnv) -> NDArray[np.float64]:
        return np.asarray(soccer_crowd(env.world).goal, dtype=np.float64)

    def _ball_front_of_keeper(self, env: LocalizationEnv) -> NDArray[np.float64]:
        keeper = self._keeper_xy(env)
        goal = self._goal_xy(env)
        sc = soccer_crowd(env.world).soccer
        origin = keeper if keeper is not None else goal
        into_field = _unit(np.array([2.5, 2.5]) - goal)
        return origin + into_field * (sc.radius_m + sc.ball_radius_m + 0.03)

    # -------------------------------------------------------------------- phases
    def _enter(self, env: LocalizationEnv, phase: int) -> None:
        self.phase = phase
        self._phase_start_s = env.world.time_s

    def _start_play(self, env: LocalizationEnv) -> None:
        self.plays += 1
        set_ball(env.world, self._ball_front_of_keeper(env))
        w, _ = self._field(env)
        self._wait_xy = np.array([self.rng.uniform(1.0, w - 1.0), self.rng.uniform(1.2, 2.5)])
        self._enter(env, self.KICKOFF)

    def act(self, env: LocalizationEnv) -> Action:
        world = env.world
        t = world.time_s
        pose = world.robot_pose
        ball = np.asarray(world.positions[world.ball_row], dtype=np.float64)
        ball_v = np.asarray(world.velocities[world.ball_row], dtype=np.float64)
        robot_r = env.config.robot.radius_m
        ball_r = soccer_crowd(world).soccer.ball_radius_m
        elapsed = t - self._phase_start_s
        heading = np.array([math.cos(pose[2]), math.sin(pose[2])])

        if self.phase == self.KICKOFF:
            set_ball(world, self._ball_front_of_keeper(env))  # the keeper holds the ball
            if elapsed >= self.kickoff_s:
                angle = -math.pi / 2 + self.rng.uniform(-self.kick_out_spread_rad, self.kick_out_spread_rad)
                speed = self.rng.uniform(*self.kick_out_speed_mps)
                set_ball(world, ball, speed * np.array([math.cos(angle), math.sin(angle)]))
                self._enter(env, self.CHASE)
            return steer(pose, self._wait_xy, self.chase_speed_mps, env)

        if self.phase == self.AFTER_SHOT:
            if elapsed >= self.after_shot_s:
                self._start_play(env)
            return steer(pose, self._wait_xy, self.chase_speed_mps, env)

        goal = self._goal_xy(env)
        if self.phase == self.CHASE:
            to_goal = _unit(goal - ball)
            to_ball = ball - pose[:2]
            dist = float(np.hypot(*to_ball))
            reach = robot_r + ball_r + 0.08
            facing = dist > 1e-6 and float(np.dot(heading, to_ball / dist)) > math.cos(math.radians(30))
            if dist < reach and facing and float(np.hypot(*ball_v)) < 1.0:
                self._enter(env, self.DRIBBLE)
            else:
                ahead = ball + ball_v * 0.4
                behind_ok = dist > 1e-6 and float(np.dot(to_ball / dist, to_goal)) > 0.7
                target = ahead if behind_ok else ahead - to_goal * (robot_r + ball_r + 0.2)
                return steer(pose, self._clip(env, target), self.chase_speed_mps, env)

        if self.phase == self.DRIBBLE:
            if pose[1] >= self.shoot_line_y_m or elapsed >= self.max_dribble_s:
                keeper = self._keeper_xy(env)
                keeper_x = float(keeper[0]) if keeper is not None else float(goal[0])
                side = -0.75 if keeper_x >= goal[0] else 0.75  # the open side of the goal
                self._aim_xy = np.array([goal[0] + side, goal[1]])
                self._enter(env, self.AIM)
            else:
                action = steer(pose, np.array([goal[0], self.shoot_line_y_m + 0.3]), self.dribble_speed_mps, env)
                self._hold_ball(env, action)
                return action

        # AIM: turn in place holding the ball, then kick
        d = self._aim_xy - pose[:2]
        direction = math.atan2(d[1], d[0])
        if abs(float(wrap_angle(direction - pose[2]))) < math.radians(4.0) or t - self._phase_start_s > 2.0:
            set_ball(world, pose[:2] + heading * (robot_r + ball_r + 0.01), self.shot_speed_mps * heading)
            self.shots += 1
            self._enter(env, self.AFTER_SHOT)
            return steer(pose, self._wait_xy, self.chase_speed_mps, env)
        action = turn_toward(pose, direction, env)
        self._hold_ball(env, action)
        return action

    def _hold_ball(self, env: LocalizationEnv, action: Action) -> None:
        """Dribbling: the ball sits just in front of the robot and moves with it this step."""
        pose = env.world.robot_pose
        heading = np.array([math.cos(pose[2]), math.sin(pose[2])])
        gap = env.config.robot.radius_m + soccer_crowd(env.world).soccer.ball_radius_m + 0.01
        v = float(action[0]) * env.max_speed_mps
        set_ball(env.world, pose[:2] + heading * gap, v * heading)


class PatrolDriver:
    """Drive a closed loop of waypoints forever, steering on the true pose (the robot's own control).

    Args:
        waypoints: ``(x, y)`` corners, visited in order, cyclically.
        speed_mps: cruise speed.
        arrive_m: a waypoint is reached within this distance.
    """

    def __init__(self, waypoints: Sequence[tuple[float, float]], speed_mps: float = 0.8, arrive_m: float = 0.15) -> None:
        self.waypoints = [np.asarray(w, dtype=np.float64) for w in waypoints]
        self.speed_mps = speed_mps
        self.arrive_m = arrive_m
        self._next = 0

    @property
    def done(self) -> bool:
        return False

    def reset(self, env: LocalizationEnv) -> None:
        pose = env.world.robot_pose
        self._next = int(np.argmin([np.hypot(*(w - pose[:2])) for w in self.waypoints]))

    def act(self, env: LocalizationEnv) -> Action:
        pose = env.world.robot_pose
        if np.hypot(*(self.waypoints[self._next] - pose[:2])) < self.arrive_m:
            self._next = (self._next + 1) % len(self.waypoints)
        return steer(pose, self.waypoints[self._next], self.speed_mps, env, brake_m=0.05)


class ShoveDriver:
    """Wraps a driver and, at ``push_time_s``, drives crowd member ``member`` into the robot.

    Until the push the member is parked (held) at ``park_xy``, outside the field so that it
    hides no landmark. At the push it is put ``start_gap_m`` beside the robot (to its left),
    released and sent through the robot's position to a point ``overshoot_m`` beyond it, at
    the crowd's speed; after ``duration_s`` it is parked again. The push moves our robot
    without any odometry reading it, a pose jump.

    Args:
        inner: the driver that moves our robot.
        push_time_s: when the shove starts.
        member: crowd member index (must not be the keeper).
        duration_s: how long the member keeps pushing.
        park_xy: where the member waits.
    """

    def __init__(
        self,
        inner: Driver,
        push_time_s: float,
        *,
        member: int = 1,
        duration_s: float = 1.0,
        start_gap_m: float = 0.1,
        overshoot_m: float = 1.0,
        park_xy: tuple[float, float] = (5.3, 2.5),
    ) -> None:
        self.inner = inner
        self.push_time_s = push_time_s
        self.member = member
        self.duration_s = duration_s
        self.start_gap_m = start_gap_m
        self.overshoot_m = overshoot_m
        self.park_xy = park_xy
        self.state = "parked"

    @property
    def done(self) -> bool:
        return self.inner.done

    def reset(self, env: LocalizationEnv) -> None:
        env.world.place_crowd_member(self.member, self.park_xy, hold=True)
        self.state = "parked"
        self.inner.reset(env)

    def _shover(self, world: World) -> tuple[SoccerCrowd, int]:
        """The soccer crowd and the index in it of the pushing member."""
        crowd, index = world.crowd_of_member(self.member)
        if not isinstance(crowd, SoccerCrowd):
            raise ValueError(f"the shove needs a soccer crowd member; member {self.member} is in {crowd.name!r}")
        return crowd, index

    def act(self, env: LocalizationEnv) -> Action:
        world = env.world
        t = world.time_s
        if self.state == "parked" and t >= self.push_time_s:
            pose = world.robot_pose
            left = np.array([-math.sin(pose[2]), math.cos(pose[2])])
            crowd, index = self._shover(world)
            gap = env.config.robot.radius_m + crowd.config.radius_m + self.start_gap_m
            world.place_crowd_member(self.member, tuple(pose[:2] + left * gap), hold=False)
            crowd.send(index, pose[:2] - left * self.overshoot_m, t + self.duration_s + 1.0)
            self.state = "pushing"
        elif self.state == "pushing":
            if t >= self.push_time_s + self.duration_s:
                world.place_crowd_member(self.member, self.park_xy, hold=True)
                self.state = "done"
            else:  # keep pressing: aim through the robot's current position
                robot = world.positions[0]
                crowd, index = self._shover(world)
                away = _unit(robot - world.positions[crowd.rows[index]])
                crowd.send(index, robot + away * self.overshoot_m)
        return self.inner.act(env)


def kidnap(
    world: World,
    rng: np.random.Generator,
    min_distance_m: float = 2.0,
    attempts: int = 10_000,
    *,
    max_distance_m: float = math.inf,
    keep_heading: bool = False,
) -> NDArray[np.float64]:
    """Carry our robot away: teleport it to a random free pose at least ``min_distance_m`` from
    where it stands, with a random heading (odometry does not see it). Returns the new pose.

    The pose is drawn uniformly over the arena (``WorldConfig.arena_m``), heading uniform,
    until the robot's disc fits there (:meth:`envs.world.World.robot_placement_problem`) and
    no crowd member's footprint disc overlaps it. With a finite ``max_distance_m`` the position
    is drawn over the arena's part within ``max_distance_m`` of the robot (along each axis) and
    refused beyond it: a short jump (e.g. 2-5 m), uniform over the ring's free part. With
    ``keep_heading`` the robot keeps its heading (a pure translation; the heading is still drawn,
    so the positions are those of the same draws). With the defaults the draws are those without these options.

    Raises:
        ValueError: when ``min_distance_m`` is not a finite number >= 0, ``max_distance_m`` not a
            number above it, or no such pose was found in ``attempts`` draws (the arena is too small
            for the distance, or the ring too crowded).
    """
    if not (math.isfinite(min_distance_m) and min_distance_m >= 0.0):
        raise ValueError(f"kidnap: min_distance_m must be a finite number of metres >= 0, got {min_distance_m!r}")
    if not max_distance_m > min_distance_m:  # false for NaN
        raise ValueError(f"kidnap: max_distance_m must be above min_distance_m {min_distance_m!r}, got {max_distance_m!r}")
    here = world.robot_pose.copy()
    xmin, ymin, xmax, ymax = world.config.arena_m
    if math.isfinite(max_distance_m):
        xmin, xmax = max(xmin, here[0] - max_distance_m), min(xmax, here[0] + max_distance_m)
        ymin, ymax = max(ymin, here[1] - max_distance_m), min(ymax, here[1] + max_distance_m)
    others, radii = world.positions[1:], world.radii_m[1:]
    r = world.config.robot.radius_m
    for _ in range(attempts):
        x, y, theta = rng.uniform(xmin, xmax), rng.uniform(ymin, ymax), rng.uniform(-math.pi, math.pi)
        distance = math.hypot(x - here[0], y - here[1])
        if not min_distance_m <= distance <= max_distance_m or world.robot_placement_problem(x, y) is not None:
            continue
        if others.shape[0] and np.any(np.hypot(others[:, 0] - x, others[:, 1] - y) < radii + r):
            continue
        pose = np.array([x, y, float(here[2]) if keep_heading else theta])
        world.set_robot_pose(pose)
        return pose
    ring = f"{min_distance_m:g}-{max_distance_m:g} m" if math.isfinite(max_distance_m) else f"at least {min_distance_m:g} m"
    raise ValueError(
        f"kidnap: no free pose {ring} from {here[:2].round(3).tolist()} in {attempts} draws "
        f"over arena {world.config.arena_m} of world {world.config.name!r}"
    )
