"""The physical world: a pymunk space with walls, landmark poles, our robot and the crowds.

The crowds (:mod:`envs.crowds`) own their bodies and decide what they want every step from
a frozen :class:`~envs.state.WorldState`; the world turns that into pymunk bodies, forces
and contacts. Scripted drivers steer through the public control methods
(:meth:`World.place_body`, :meth:`World.place_crowd_member`, :meth:`World.crowd_named`).

Pymunk does the dynamics and contacts only. After every physics step the world exports
its state as numpy arrays (``positions``, ``velocities``, wall segments, every body's parts by
height: :mod:`envs.bodies`),
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

from envs.bodies import turn_to_travel
from envs.config import BOUNDARY_SEGMENTS, WALL_RADIUS_M, WorldConfig
from envs.crowds import BodySpec, Crowd, build_crowd
from envs.figure_model import FigureModel
from envs.figures import Figures, consecutive
from envs.state import Rows, WorldState, robot_pose

# collision types
ROBOT, CROWD, BALL, WALL, LANDMARK = 1, 2, 3, 4, 5
KIND_NAMES = {ROBOT: "robot", CROWD: "crowd", BALL: "ball", WALL: "wall", LANDMARK: "landmark"}

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
    v_now: NDArray[np.float64], v_want: NDArray[np.float64], dt: float, max_accel: float, mass: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Forces ``(N, 2)`` that bring velocities ``v_now`` to ``v_want`` in one step, capped at
    ``max_accel``, for bodies of ``mass`` ``(N,)``."""
    out = np.empty_like(v_now)
    for i in range(v_now.shape[0]):
        ax = (v_want[i, 0] - v_now[i, 0]) / dt
        ay = (v_want[i, 1] - v_now[i, 1]) / dt
        a = math.sqrt(ax * ax + ay * ay)
        scale = mass[i] * (min(1.0, max_accel / a) if a > 0 else 1.0)
        out[i, 0] = ax * scale
        out[i, 1] = ay * scale
    return out


class World:
    """Builds and steps one scenario.

    Attributes:
        config: the validated scenario.
        seg_a, seg_b: ``(S, 2)`` wall segments (static; occlude and collide).
        landmark_xy: ``(L, 2)``, ``landmark_radius_m``: ``(L,)``, ``landmark_max_range_m``: ``(L,)``.
        crowds: the crowd plug-ins by name, in config order.
        positions: ``(B, 2)`` body positions after the last step; row 0 is our robot, then
            each crowd's bodies in config order (its members, then e.g. its ball).
        angles: ``(B,)``; ``velocities``: ``(B, 2)``.
        member_rows, ball_rows: rows of every crowd member (robots, people) and of the balls.
        contacts: the :class:`ContactEvent` s of the last step only; ``contact_count``: how
            many the episode has had.
    """

    def __init__(self, config: WorldConfig) -> None:
        self.config = config
        self.time_s = 0.0
        self.step_count = 0
        #: the contacts our robot started during the last step only (a fresh list every step,
        #: so memory stays bounded over any episode); ``contact_count`` counts the episode's
        self.contacts: list[ContactEvent] = []
        self.contact_count = 0
        self._wall_segments()
        lms = config.landmarks
        self.landmark_names = tuple(lm.name for lm in lms)
        self.landmark_xy = np.asarray([(lm.x_m, lm.y_m) for lm in lms], dtype=np.float64).reshape(-1, 2)
        self.landmark_radius_m = np.asarray([lm.radius_m for lm in lms], dtype=np.float64)
        self.landmark_max_range_m = np.asarray([lm.max_range_m for lm in lms], dtype=np.float64)

        #: the crowds by name, in config order; their bodies follow the robot in that order
        self.crowds: dict[str, Crowd] = {name: build_crowd(name, cc, config) for name, cc in config.crowds.items()}
        self._specs: list[BodySpec] = []
        self._owner: list[tuple[Crowd, int]] = []  # per body row after the robot: (crowd, index in it)
        for crowd in self.crowds.values():
            specs = crowd.bodies()
            first = 1 + len(self._specs)
            crowd.attach(np.arange(first, first + len(specs), dtype=np.int64))
            self._specs += specs
            self._owner += [(crowd, i) for i in range(len(specs))]
        self.body_count = 1 + len(self._specs)
        kinds = np.array(["robot"] + [b.kind for b in self._specs])
        #: rows of the crowds' members (robots, people), and of the balls
        self.member_rows = np.flatnonzero(kinds == "crowd")
        self.crowd_rows = _as_slice(self.member_rows)
        self.ball_rows = np.flatnonzero(kinds == "ball")
        self.ball_row = int(self.ball_rows[0]) if self.ball_rows.size else -1
        self.radii_m = np.asarray([config.robot.radius_m] + [b.radius_m for b in self._specs], dtype=np.float64)
        #: every body's vertical profile (:mod:`envs.bodies`): what the sensors see at their heights
        self.figure_model = FigureModel([(b.shape, b.radius_m, b.height_m, b.occludes, b.sizes) for b in self._specs])
        #: rows of the cars: their footprint is a box that turns to face their travel
        self.car_rows = np.array([i + 1 for i, b in enumerate(self._specs) if b.shape == "car"], dtype=np.int64)
        self._has_cars, self._has_people = bool(self.car_rows.size), self.figure_model.has_people
        self._car_turn_rate = np.array([b.car.turn_rate_rps for b in self._specs if b.shape == "car" and b.car is not None])
        self._others = _as_slice(np.concatenate([[0], self.member_rows]).astype(np.int64))  # the robot and every member
        statics = (
            self.seg_a,
            self.seg_b,
            self.seg_bottom_m,
            self.seg_top_m,
            self.landmark_xy,
            self.landmark_radius_m,
            self.landmark_max_range_m,
            self.radii_m,
        )
        for static in statics:
            static.setflags(write=False)  # shared by every snapshot
        self._state_buffer = pbatch.Buffer()
        # per body (vx, vy, omega, fx, fy), the layout pymunk.batch expects for _FIELDS_COMMAND
        self._command = np.zeros((self.body_count + 1, 5), dtype=np.float64)
        self._command_buffer = pbatch.Buffer()
        self._command_buffer.set_float_buf(self._command.reshape(-1))
        self._state = np.zeros((self.body_count, 5))
        self._build_space()
        self._robot_start = self._state[0, 0:3]

    # ------------------------------------------------------------------ construction
    def _wall_segments(self) -> None:
        """The arena boundary (counter-clockwise) and extra walls, as the sensors see them."""
        self._boundary_count = BOUNDARY_SEGMENTS
        segments = self.config.static_segments()
        self.seg_a, self.seg_b = np.ascontiguousarray(segments[:, 0:2]), np.ascontiguousarray(segments[:, 2:4])
        #: ``(S,)`` each segment's bottom and top: a sensor sees it at heights in [bottom, top)
        self.seg_bottom_m, self.seg_top_m = np.ascontiguousarray(segments[:, 4]), np.ascontiguousarray(segments[:, 5])
        #: the segments that stand on the floor and collide (a table's top is above the bodies)
        self._colliding = self.seg_bottom_m <= 0.0

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
            if not self._colliding[i]:
                continue
            radius = WALL_RADIUS_M
            if i < self._boundary_count:
                # thick boundary walls whose inner face is the arena edge: nothing is squeezed through
                radius = _BOUNDARY_RADIUS_M
                d = b - a
                outward = np.array([d[1], -d[0]]) / np.hypot(*d) * radius
                a, b = a + outward, b + outward
            wall = pymunk.Segment(self.space.static_body, tuple(a), tuple(b), radius)
            wall.elasticity = 0.5
            wall.friction = 0.5
            wall.collision_type = WALL
            self.space.add(wall)
        for lm, (x, y), r in zip(config.landmarks, self.landmark_xy, self.landmark_radius_m):
            if not lm.collides:
                continue
            pole = pymunk.Circle(self.space.static_body, float(r), (float(x), float(y)))
            pole.collision_type = LANDMARK
            self.space.add(pole)

        rc = config.robot
        self.robot_body = pymunk.Body(rc.mass_kg, pymunk.moment_for_circle(rc.mass_kg, 0, rc.radius_m))
        self.robot_shape = pymunk.Circle(self.robot_body, rc.radius_m)
        self.robot_shape.friction = rc.friction
        self.robot_shape.collision_type = ROBOT
        self.space.add(self.robot_body, self.robot_shape)
        self.bodies: list[pymunk.Body] = []  # per row after the robot
        member = 0
        for spec in self._specs:
            shape: pymunk.Shape
            if spec.shape == "car" and spec.car is not None:  # a box that contacts do not spin (it steers to its travel)
                body = pymunk.Body(spec.mass_kg, math.inf)
                shape = pymunk.Poly.create_box(body, (spec.car.length_m, spec.car.width_m))
            else:
                body = pymunk.Body(spec.mass_kg, pymunk.moment_for_circle(spec.mass_kg, 0, spec.radius_m))
                shape = pymunk.Circle(body, spec.radius_m)
            shape.friction = spec.friction
            if spec.elasticity:
                shape.elasticity = spec.elasticity
            shape.collision_type = CROWD if spec.kind == "crowd" else BALL
            if spec.kind == "crowd":
                shape.crowd_index = member  # type: ignore[attr-defined]
                member += 1
            self.space.add(body, shape)
            self.bodies.append(body)
        self.space.on_collision(ROBOT, None, begin=self._on_robot_contact)
        self._check_body_order()
        self.read_state()

    def _check_body_order(self) -> None:
        buf = pbatch.Buffer()
        pbatch.get_space_bodies(self.space, pbatch.BodyFields.BODY_ID, buf)
        ids = np.frombuffer(buf.int_buf(), dtype=np.uintp)
        expected = [self.robot_body.id] + [b.id for b in self.bodies] + [self.space.static_body.id]
        if ids.tolist() != expected:
            raise RuntimeError("pymunk iterated the bodies in an unexpected order; batch I/O would mix them up")

    # ------------------------------------------------------------------ episode
    def reset(self, rng: np.random.Generator) -> None:
        """Rebuild the space and place the robot and the crowd for a new episode."""
        self.time_s = 0.0
        self.step_count = 0
        self.contacts = []
        self.contact_count = 0
        self._build_space()
        rc = self.config.robot
        if rc.start_pose is not None:
            pose = rc.start_pose
        else:
            assert rc.start_region_m is not None
            x0, y0, x1, y1 = rc.start_region_m
            pose = (rng.uniform(x0, x1), rng.uniform(y0, y1), rng.uniform(-math.pi, math.pi))
        self.set_robot_pose(pose)
        taken = [(float(pose[0]), float(pose[1]), rc.radius_m)]
        for crowd in self.crowds.values():
            placed = crowd.reset(rng, taken)
            headings = crowd.start_headings()
            for k, (row, (x, y)) in enumerate(zip(crowd.rows, placed)):
                body = self.bodies[row - 1]
                body.position = (float(x), float(y))
                body.velocity = (0.0, 0.0)
                body.angle = 0.0 if headings is None else float(headings[k])
                body.angular_velocity = 0.0
        for body in self.space.bodies:
            self.space.reindex_shapes_for_body(body)
        self.read_state()
        self.figure_model.reset(rng, self.velocities)

    def robot_placement_problem(self, x: float, y: float) -> str | None:
        """Why our robot's disc cannot be placed at ``(x, y)``, or None where it fits
        (:meth:`WorldConfig.robot_placement_problem`: the one rule for reset poses and the config's start)."""
        return self.config.robot_placement_problem(x, y)

    def set_robot_pose(self, pose: tuple[float, float, float] | NDArray[np.float64]) -> None:
        """Teleport our robot (tests and scripted set-ups only; odometry does not see it)."""
        self.robot_body.position = (float(pose[0]), float(pose[1]))
        self.robot_body.angle = float(pose[2])
        self.robot_body.velocity = (0.0, 0.0)
        self.robot_body.angular_velocity = 0.0
        self.space.reindex_shapes_for_body(self.robot_body)
        self.read_state()
        self._robot_start = self._state[0, 0:3]  # a jump, not a motion: the step starts here

    def place_body(
        self, row: int, xy: tuple[float, float], velocity: tuple[float, float] = (0.0, 0.0), angle: float | None = None
    ) -> None:
        """Teleport the body in ``row`` (scripted set-ups: a referee's ball, a shove, a parked
        car turned to ``angle``; None keeps its heading); odometry does not see it."""
        if not 1 <= row < self.body_count:
            raise IndexError(f"body row {row} does not exist (rows 1..{self.body_count - 1} are the crowds' bodies)")
        if angle is not None and not math.isfinite(angle):
            raise ValueError(f"place_body: angle must be finite, got {angle}")
        body = self.bodies[row - 1]
        body.position = (float(xy[0]), float(xy[1]))
        body.velocity = (float(velocity[0]), float(velocity[1]))
        if angle is not None:
            body.angle = float(angle)
        self.space.reindex_shapes_for_body(body)
        self.read_state()

    def place_crowd_member(self, index: int, xy: tuple[float, float], hold: bool = True, angle: float | None = None) -> None:
        """Teleport crowd member ``index`` (counted over every crowd's members, in order); ``hold``
        freezes it there; ``angle`` turns it (a car; None keeps its heading)."""
        crowd, i = self.crowd_of_member(index)
        crowd.hold(i, hold)
        self.place_body(int(self.member_rows[index]), xy, angle=angle)

    def crowd_named(self, name: str) -> Crowd:
        """The crowd called ``name`` in the world config (its public control methods)."""
        if name not in self.crowds:
            raise KeyError(f"world {self.config.name!r} has no crowd {name!r} (crowds: {', '.join(self.crowds) or 'none'})")
        return self.crowds[name]

    def crowd_of_member(self, index: int) -> tuple[Crowd, int]:
        """``(crowd, index within it)`` of crowd member ``index`` (counted over every crowd)."""
        if not 0 <= index < self.member_rows.size:
            raise IndexError(f"crowd member {index} does not exist (crowd has {self.member_rows.size})")
        return self._owner[int(self.member_rows[index]) - 1]

    @property
    def robot_pose(self) -> NDArray[np.float64]:
        """``(3,)`` true pose of our robot, heading wrapped to ``[-pi, pi)`` (:attr:`WorldState.robot_pose`)."""
        return robot_pose(self.positions, self.angles)

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
        self._figures: Figures | None = None

    @property
    def figures(self) -> Figures:
        """Every body's parts at the current step (made once per step, on first use)."""
        if self._figures is None:
            self._figures = self.figure_model.pose(self.positions, self.angles)
        return self._figures

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
                seg_a=self.seg_a,
                seg_b=self.seg_b,
                seg_bottom_m=self.seg_bottom_m,
                seg_top_m=self.seg_top_m,
                figures=self.figures,
                landmark_xy=self.landmark_xy,
                landmark_radius_m=self.landmark_radius_m,
                landmark_max_range_m=self.landmark_max_range_m,
                landmark_names=self.landmark_names,
                robot_start=self._robot_start,
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
        state = self.snapshot()
        turned: list[int] = []  # rows a crowd turned to a heading: no turn rate this step
        for crowd in self.crowds.values():
            if not crowd.rows.size:
                continue
            wants = crowd.commands(state, self._others, rng)
            rows = crowd.member_rows
            cmd[rows, 0:2] = self.velocities[rows]
            cmd[rows, 3:5] = _driving_forces(
                self.velocities[rows], wants.member_velocity, dt, _CROWD_MAX_ACCEL_MPS2, crowd.member_mass_kg
            )
            if wants.ball_velocity is not None:
                cmd[crowd.rows[crowd.count], 0:2] = wants.ball_velocity
            for index, xy in wants.teleports:
                row = int(crowd.rows[index])
                body = self.bodies[row - 1]
                body.position = (float(xy[0]), float(xy[1]))
                cmd[row, 0:2] = 0.0
                self.space.reindex_shapes_for_body(body)
            for index, heading in wants.headings:
                row = int(crowd.rows[index])
                body = self.bodies[row - 1]
                body.angle = float(heading)
                turned.append(row)
                if any(i == index for i, _ in wants.teleports):  # moved and turned: on at its speed, no force
                    speed = math.hypot(*self.velocities[row])
                    cmd[row, 0:2] = (speed * math.cos(heading), speed * math.sin(heading))
                    cmd[row, 3:5] = 0.0
                self.space.reindex_shapes_for_body(body)
        if self._has_cars:
            cars = self.car_rows
            cmd[cars, 2] = turn_to_travel(self.angles[cars], self.velocities[cars], dt, self._car_turn_rate)
        if turned:
            cmd[turned, 2] = 0.0
        pbatch.set_space_bodies(self.space, _FIELDS_COMMAND, self._command_buffer)
        self.contacts = []  # a new list: one handed out for the last step is never changed
        self._robot_start = self._state[0, 0:3]  # (a view: read_state makes a fresh array, this one is never written)
        self.space.step(dt)
        self.time_s += dt
        self.step_count += 1
        self.read_state()
        if self._has_people:  # (the gait; nothing to move without people)
            self.figure_model.advance(self.velocities, dt)

    def robot_touching(self) -> bool:
        """Whether our robot is in contact with anything (a wall, a pole, a crowd member, the
        ball) after the last physics step: its body holds an arbiter with contact points.

        Unlike :attr:`contacts` (the contacts that *began* in the last step) this stays true
        for as long as the robot presses on, or is pressed by, something.
        """
        touching = False

        def see(arbiter: pymunk.Arbiter) -> None:
            nonlocal touching
            touching = touching or bool(arbiter.contact_point_set.points)

        self.robot_body.each_arbiter(see)
        return touching

    def _on_robot_contact(self, arbiter: pymunk.Arbiter, space: pymunk.Space, data: object) -> None:
        other = arbiter.shapes[1] if arbiter.shapes[0].collision_type == ROBOT else arbiter.shapes[0]
        kind = KIND_NAMES.get(other.collision_type, "other")
        index = int(getattr(other, "crowd_index", -1))
        point = arbiter.contact_point_set.points[0].point_a if arbiter.contact_point_set.points else self.robot_body.position
        self.contacts.append(ContactEvent(self.step_count + 1, kind, index, (float(point[0]), float(point[1]))))
        self.contact_count += 1


def _as_slice(rows: NDArray[np.int64]) -> Rows:
    """Consecutive rows as a slice (views, no copies per step), else the index array; no rows: an empty slice after the robot."""
    return slice(1, 1) if rows.size == 0 else consecutive(rows)
