"""The physical world: a pymunk space with walls, landmark poles, our robot and the crowd.

Pymunk does the dynamics and contacts only. After every physics step the world exports
its state as numpy arrays (``positions``, ``velocities``, occluder circles, wall segments),
which the sensors ray-cast against; no per-ray pymunk query is made anywhere.

Body state moves in and out of pymunk through ``pymunk.batch`` in one call each way.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np
import pymunk
import pymunk.batch as pbatch
from numpy.typing import NDArray

from envs.config import WorldConfig
from envs.crowd import Crowd, make_crowd
from envs.state import WorldState

# collision types
ROBOT, CROWD, BALL, WALL, LANDMARK = 1, 2, 3, 4, 5
KIND_NAMES = {ROBOT: "robot", CROWD: "crowd", BALL: "ball", WALL: "wall", LANDMARK: "landmark"}

_WALL_RADIUS_M = 0.02  # extra (interior) walls
_BOUNDARY_RADIUS_M = 0.15  # boundary walls, laid outside the arena edge
_COLLISION_SLOP_M = 0.002
_COLLISION_BIAS = 1e-30  # fraction of an overlap left after one second
_FIELDS_STATE = pbatch.BodyFields.POSITION | pbatch.BodyFields.ANGLE | pbatch.BodyFields.VELOCITY
_FIELDS_COMMAND = pbatch.BodyFields.VELOCITY | pbatch.BodyFields.ANGULAR_VELOCITY | pbatch.BodyFields.FORCE
_CROWD_MAX_ACCEL_MPS2 = 30.0  # crowd members reach 1.75 m/s in two steps, and push no harder


@dataclass(frozen=True)
class ContactEvent:
    """Our robot started touching something during a step."""

    step: int
    other: str  # "crowd", "ball", "wall" or "landmark"
    other_index: int  # crowd member index, or -1
    position_xy_m: tuple[float, float]


@numba.njit(cache=True)
def _driving_forces(
    v_now: NDArray[np.float64], v_want: NDArray[np.float64], dt: float, max_accel: float, mass: float
) -> NDArray[np.float64]:
    """Forces ``(N, 2)`` that bring velocities ``v_now`` to ``v_want`` in one step, capped at ``max_accel``."""
    out = np.empty_like(v_now)
    for i in range(v_now.shape[0]):
        ax = (v_want[i, 0] - v_now[i, 0]) / dt
        ay = (v_want[i, 1] - v_now[i, 1]) / dt
        a = math.sqrt(ax * ax + ay * ay)
        scale = mass * (min(1.0, max_accel / a) if a > 0 else 1.0)
        out[i, 0] = ax * scale
        out[i, 1] = ay * scale
    return out


class World:
    """Builds and steps one scenario.

    Attributes:
        config: the validated scenario.
        seg_a, seg_b: ``(S, 2)`` wall segments (static; occlude and collide).
        landmark_xy: ``(L, 2)``, ``landmark_radius_m``: ``(L,)``, ``landmark_max_range_m``: ``(L,)``.
        positions: ``(B, 2)`` body positions after the last step; row 0 is our robot,
            rows ``1..1+N`` the crowd, then the ball if any.
        angles: ``(B,)``; ``velocities``: ``(B, 2)``.
        occluder_rows: rows of ``positions`` whose circles block sight (``occluder_radius_m``).
    """

    def __init__(self, config: WorldConfig) -> None:
        self.config = config
        self.time_s = 0.0
        self.step_count = 0
        self.contacts: list[ContactEvent] = []
        self._wall_segments()
        lms = config.landmarks
        self.landmark_names = tuple(lm.name for lm in lms)
        self.landmark_xy = np.asarray([(lm.x_m, lm.y_m) for lm in lms], dtype=np.float64).reshape(-1, 2)
        self.landmark_radius_m = np.asarray([lm.radius_m for lm in lms], dtype=np.float64)
        self.landmark_max_range_m = np.asarray([lm.max_range_m for lm in lms], dtype=np.float64)

        self.crowd: Crowd = make_crowd(config)
        has_ball = self.crowd.has_ball
        # body rows: robot, crowd..., ball?, then pymunk's static body (batch iterates it too)
        self.body_count = 1 + self.crowd.count + (1 if has_ball else 0)
        self.crowd_rows = slice(1, 1 + self.crowd.count)
        self.ball_row = 1 + self.crowd.count if has_ball else -1
        radii = [config.robot.radius_m] + list(self.crowd.radii_m)
        if has_ball:
            radii.append(config.crowd.soccer.ball_radius_m)
        self.radii_m = np.asarray(radii, dtype=np.float64)
        # occluders are the rows right after the robot: the crowd, and the ball if it occludes
        ball_occludes = has_ball and config.crowd.soccer.ball_occludes
        self.occluder_rows = slice(1, 1 + self.crowd.count + (1 if ball_occludes else 0))
        self.occluder_radius_m = self.radii_m[self.occluder_rows].copy()
        for static in (self.seg_a, self.seg_b, self.landmark_xy, self.landmark_radius_m, self.landmark_max_range_m, self.radii_m):
            static.setflags(write=False)  # shared by every snapshot
        self._state_buffer = pbatch.Buffer()
        # per body (vx, vy, omega, fx, fy), the layout pymunk.batch expects for _FIELDS_COMMAND
        self._command = np.zeros((self.body_count + 1, 5), dtype=np.float64)
        self._command_buffer = pbatch.Buffer()
        self._command_buffer.set_float_buf(self._command.reshape(-1))
        self._state = np.zeros((self.body_count, 5))
        self._build_space()

    # ------------------------------------------------------------------ construction
    def _wall_segments(self) -> None:
        """The arena boundary (counter-clockwise) and extra walls, as the sensors see them."""
        xmin, ymin, xmax, ymax = self.config.arena_m
        boundary = [
            (xmin, ymin, xmax, ymin),
            (xmax, ymin, xmax, ymax),
            (xmax, ymax, xmin, ymax),
            (xmin, ymax, xmin, ymin),
        ]
        self._boundary_count = len(boundary)
        arr = np.asarray(boundary + [tuple(s) for s in self.config.walls], dtype=np.float64).reshape(-1, 4)
        self.seg_a = np.ascontiguousarray(arr[:, :2])
        self.seg_b = np.ascontiguousarray(arr[:, 2:])

    def _build_space(self) -> None:
        """A fresh pymunk space with every body; called on construction and on every reset.

        Rebuilding (about a millisecond) rather than moving bodies makes a reset forget
        chipmunk's cached contacts and correction velocities, so the same seed replays
        the same episode on a reused env.
        """
        config = self.config
        self.space = pymunk.Space()
        self.space.iterations = 10
        # Velocities are commanded before every step and chipmunk integrates positions before
        # it solves contacts, so overlaps are undone by the positional bias alone: allow only
        # millimetres of slop (the default, 0.1, is 10 cm in metres) and remove ~90 % of an
        # overlap per 1/30 s step. Pressing into an obstacle then overlaps it by at most one
        # step's travel.
        self.space.collision_slop = _COLLISION_SLOP_M
        self.space.collision_bias = _COLLISION_BIAS
        for i, (a, b) in enumerate(zip(self.seg_a, self.seg_b)):
            radius = _WALL_RADIUS_M
            if i < self._boundary_count:
                # thick boundary walls whose inner face is the arena edge: nothing is squeezed through
                radius = _BOUNDARY_RADIUS_M
                d = b - a
                outward = np.array([d[1], -d[0]]) / np.hypot(*d) * radius
                a, b = a + outward, b + outward
            shape = pymunk.Segment(self.space.static_body, tuple(a), tuple(b), radius)
            shape.elasticity = 0.5
            shape.friction = 0.5
            shape.collision_type = WALL
            self.space.add(shape)
        for (x, y), r in zip(self.landmark_xy, self.landmark_radius_m):
            shape = pymunk.Circle(self.space.static_body, float(r), (float(x), float(y)))
            shape.collision_type = LANDMARK
            self.space.add(shape)

        rc = config.robot
        self.robot_body = pymunk.Body(rc.mass_kg, pymunk.moment_for_circle(rc.mass_kg, 0, rc.radius_m))
        self.robot_shape = pymunk.Circle(self.robot_body, rc.radius_m)
        self.robot_shape.friction = rc.friction
        self.robot_shape.collision_type = ROBOT
        self.space.add(self.robot_body, self.robot_shape)
        self.crowd_bodies: list[pymunk.Body] = []
        for i in range(self.crowd.count):
            radius = float(self.crowd.radii_m[i])
            body = pymunk.Body(config.crowd.mass_kg, pymunk.moment_for_circle(config.crowd.mass_kg, 0, radius))
            shape = pymunk.Circle(body, radius)
            shape.friction = 0.5
            shape.collision_type = CROWD
            shape.crowd_index = i  # type: ignore[attr-defined]
            self.space.add(body, shape)
            self.crowd_bodies.append(body)
        self.ball_body: pymunk.Body | None = None
        if self.crowd.has_ball:
            sc = config.crowd.soccer
            self.ball_body = pymunk.Body(sc.ball_mass_kg, pymunk.moment_for_circle(sc.ball_mass_kg, 0, sc.ball_radius_m))
            ball_shape = pymunk.Circle(self.ball_body, sc.ball_radius_m)
            ball_shape.elasticity = 0.7
            ball_shape.friction = 0.3
            ball_shape.collision_type = BALL
            self.space.add(self.ball_body, ball_shape)
        self.space.on_collision(ROBOT, None, begin=self._on_robot_contact)
        self._check_body_order()
        self.read_state()

    def _check_body_order(self) -> None:
        buf = pbatch.Buffer()
        pbatch.get_space_bodies(self.space, pbatch.BodyFields.BODY_ID, buf)
        ids = np.frombuffer(buf.int_buf(), dtype=np.uintp)
        expected = [self.robot_body.id] + [b.id for b in self.crowd_bodies]
        if self.ball_body is not None:
            expected.append(self.ball_body.id)
        expected.append(self.space.static_body.id)
        if ids.tolist() != expected:
            raise RuntimeError("pymunk iterated the bodies in an unexpected order; batch I/O would mix them up")

    # ------------------------------------------------------------------ episode
    def reset(self, rng: np.random.Generator) -> None:
        """Rebuild the space and place the robot and the crowd for a new episode."""
        self.time_s = 0.0
        self.step_count = 0
        self.contacts = []
        self._build_space()
        rc = self.config.robot
        if rc.start_pose is not None:
            pose = rc.start_pose
        else:
            assert rc.start_region_m is not None
            x0, y0, x1, y1 = rc.start_region_m
            pose = (rng.uniform(x0, x1), rng.uniform(y0, y1), rng.uniform(-math.pi, math.pi))
        self.set_robot_pose(pose)
        placed = self.crowd.reset(rng, robot_xy=np.asarray(pose[:2]), robot_radius_m=rc.radius_m)
        for body, (x, y) in zip(self.crowd_bodies, placed.member_xy):
            body.position = (float(x), float(y))
            body.velocity = (0.0, 0.0)
            body.angle = 0.0
            body.angular_velocity = 0.0
        if self.ball_body is not None:
            assert placed.ball_xy is not None
            self.ball_body.position = (float(placed.ball_xy[0]), float(placed.ball_xy[1]))
            self.ball_body.velocity = (0.0, 0.0)
        for body in self.space.bodies:
            self.space.reindex_shapes_for_body(body)
        self.read_state()

    def set_robot_pose(self, pose: tuple[float, float, float] | NDArray[np.float64]) -> None:
        """Teleport our robot (tests and scripted set-ups only; odometry does not see it)."""
        self.robot_body.position = (float(pose[0]), float(pose[1]))
        self.robot_body.angle = float(pose[2])
        self.robot_body.velocity = (0.0, 0.0)
        self.robot_body.angular_velocity = 0.0
        self.space.reindex_shapes_for_body(self.robot_body)
        self.read_state()

    def place_crowd_member(self, index: int, xy: tuple[float, float], hold: bool = True) -> None:
        """Teleport crowd member ``index`` (tests and scripted set-ups); ``hold`` freezes it there."""
        if not 0 <= index < self.crowd.count:
            raise IndexError(f"crowd member {index} does not exist (crowd has {self.crowd.count})")
        body = self.crowd_bodies[index]
        body.position = (float(xy[0]), float(xy[1]))
        body.velocity = (0.0, 0.0)
        self.space.reindex_shapes_for_body(body)
        self.crowd.hold(index, hold)
        self.read_state()

    @property
    def robot_pose(self) -> NDArray[np.float64]:
        """``(3,)`` true pose of our robot, heading wrapped to ``[-pi, pi)``."""
        x, y = self.positions[0]
        theta = (self.angles[0] + math.pi) % (2 * math.pi) - math.pi
        return np.array([x, y, theta])

    @property
    def occluder_xy(self) -> NDArray[np.float64]:
        return self.positions[self.occluder_rows]

    def read_state(self) -> None:
        """Copy body state out of pymunk into ``positions``, ``angles`` and ``velocities``."""
        buf = self._state_buffer
        buf.clear()
        pbatch.get_space_bodies(self.space, _FIELDS_STATE, buf)
        self._state = np.frombuffer(buf.float_buf(), dtype=np.float64).reshape(-1, 5)[: self.body_count].copy()
        self._expose_state()

    def _expose_state(self) -> None:
        # views into one fresh array per step: arrays handed out earlier are never mutated
        self.positions = self._state[:, 0:2]
        self.angles = self._state[:, 2]
        self.velocities = self._state[:, 3:5]
        self._snapshot: WorldState | None = None

    def snapshot(self) -> WorldState:
        """The frozen :class:`~envs.state.WorldState` of the current step (made once per step)."""
        if self._snapshot is None:
            self._snapshot = WorldState(
                time_s=self.time_s,
                step=self.step_count,
                positions=self.positions,
                angles=self.angles,
                velocities=self.velocities,
                radii_m=self.radii_m,
                crowd_rows=self.crowd_rows,
                ball_row=self.ball_row,
                occluder_rows=self.occluder_rows,
                seg_a=self.seg_a,
                seg_b=self.seg_b,
                landmark_xy=self.landmark_xy,
                landmark_radius_m=self.landmark_radius_m,
                landmark_max_range_m=self.landmark_max_range_m,
                landmark_names=self.landmark_names,
            )
        return self._snapshot

    # ------------------------------------------------------------------ dynamics
    def step(self, robot_velocity_xy: NDArray[np.float64], robot_omega: float, rng: np.random.Generator) -> None:
        """Advance by one time step.

        Args:
            robot_velocity_xy: ``(2,)`` world-frame velocity commanded for our robot this step.
            robot_omega: commanded turn rate (rad/s).
            rng: the world's random stream (crowd decisions).
        """
        dt = self.config.dt_s
        cmd = self._command
        # Our robot is velocity-commanded: without contacts it moves exactly as commanded, so
        # odometry and truth differ only by noise and pushes. Crowd members are force-driven
        # toward their desired velocity, which leaves their contacts to the solver.
        cmd[0, 0:2] = robot_velocity_xy
        cmd[0, 2] = robot_omega
        if self.crowd.count or self.ball_body is not None:
            member_v, ball_v = self.crowd.velocities(self, rng)
            rows = self.crowd_rows
            cmd[rows, 0:2] = self.velocities[rows]
            cmd[rows, 3:5] = _driving_forces(
                self.velocities[rows], member_v, dt, _CROWD_MAX_ACCEL_MPS2, self.config.crowd.mass_kg
            )
            if ball_v is not None:
                cmd[self.ball_row, 0:2] = ball_v
                restart = self.crowd.ball_restart(self.positions[self.ball_row])
                if restart is not None and self.ball_body is not None:
                    self.ball_body.position = (float(restart[0]), float(restart[1]))
                    cmd[self.ball_row, 0:2] = 0.0
                    self.space.reindex_shapes_for_body(self.ball_body)
        pbatch.set_space_bodies(self.space, _FIELDS_COMMAND, self._command_buffer)
        self.space.step(dt)
        self.time_s += dt
        self.step_count += 1
        self.read_state()

    def _on_robot_contact(self, arbiter: pymunk.Arbiter, space: pymunk.Space, data: object) -> None:
        other = arbiter.shapes[1] if arbiter.shapes[0].collision_type == ROBOT else arbiter.shapes[0]
        kind = KIND_NAMES.get(other.collision_type, "other")
        index = int(getattr(other, "crowd_index", -1))
        point = arbiter.contact_point_set.points[0].point_a if arbiter.contact_point_set.points else self.robot_body.position
        self.contacts.append(ContactEvent(self.step_count + 1, kind, index, (float(point[0]), float(point[1]))))
