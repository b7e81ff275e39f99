"""Fixed baseline policies with stable-baselines3's ``predict`` signature.

A fixed policy and a trained SB3 model are interchangeable in every evaluation loop:
``action, state = policy.predict(observation, state, episode_start, deterministic)``.
Policies see only the observation (the sensors and, behind ``LocalizationObservation``, the
localizer's estimate and spread) and the known map, never ``info``. Those that plan from
the estimate need the wrapped observation and say so when it is missing.

- :class:`RandomWalk`: forward at a fixed speed, turn rate a bounded random walk.
- :class:`SpinInPlace`: turn on the spot.
- :class:`PatrolPath`: an open-loop list of (speed, turn rate, duration) segments, looped
  (``"patrol"``: the Exp 1 path of the candidate-set paper, :meth:`PatrolPath.exp1`).
- :class:`StopAndGo`: alternately drive (random walk) and stand still.
- :class:`LandmarkSeeking`: head for the nearby spot from which most landmarks are in range.
- :class:`GreedyInformationGain`: one-step look-ahead over a set of motions maximizing the
  Fisher information of the bearings expected to be visible from the estimated pose.
- :class:`~agents.policies.navigation.CorridorFollower` (``"corridor_follower"``): the ceiling-target
  paper's navigation, from target to target of a ceiling along a corridor, centred by the
  side sonars, stopping under each target to correct the pose (:mod:`agents.policies.navigation`).
- :class:`~agents.policies.route_following.RouteFollower` (``"route_follower"``): pure pursuit along
  the world's route (a ``route`` feature of the map), stopping for obstacles its LIDAR or
  sonar sees ahead (:mod:`agents.policies.route_following`); ``"look_then_route"``
  (:class:`~agents.policies.route_following.LookThenRoute`) turns in place twice first, for a
  start whose pose the localizer must find (global localization).

The base class and the helpers the policies share are in :mod:`agents.policies.base`. A policy
names the sensor type it reads (``needs_sensor``) and the map feature type it plans on
(``needs_feature``); :meth:`FixedPolicy.unmet_need` says what a world lacks for it.

The last two also keep clear of the crowd when the robot has a sonar ring (observation key
``sonar``): they do not drive toward a direction whose sonar reads closer than ``clearance_m``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from gymnasium import spaces
from numpy.typing import ArrayLike, NDArray

from agents.policies.base import FixedPolicy, Observation, arc_end_poses, check_command, read_estimate, sonar_blocked, sonar_cones
from agents.policies.belief_greedy import BeliefGreedy
from agents.policies.navigation import CorridorFollower
from agents.policies.paths import EXP1_VERTICES, command_actions, polygon_commands
from agents.policies.route_following import LookThenRoute, RouteFollower, range_sensor_kwargs, route_points
from core.geometry import in_field_of_view, wrap_angle
from envs.sensors import BearingCameraConfig
from localizers.base import LandmarkMap
from localizers.bounds import bearing_information

__all__ = [
    "CLEARANCE_M",
    "FIXED_POLICIES",
    "CorridorFollower",
    "FixedPolicy",
    "GreedyInformationGain",
    "LandmarkSeeking",
    "LookThenRoute",
    "Observation",
    "PatrolPath",
    "RandomWalk",
    "RouteFollower",
    "SpinInPlace",
    "StopAndGo",
    "follows_routes",
    "make_policy",
    "read_estimate",
    "register_policy",
    "sonar_cones",
]

#: map policies do not drive toward a sonar reading closer than this (two robot radii and a margin)
CLEARANCE_M = 0.7


class RandomWalk(FixedPolicy):
    """Drive forward at a fixed speed while the turn rate follows a bounded random walk.

    Args:
        speed: forward command in ``[-1, 1]``.
        turn_noise: standard deviation of the turn-rate increments per step.
        persistence: how much of the previous turn rate is kept each step.
    """

    def __init__(
        self,
        action_space: spaces.Box,
        seed: int | None = None,
        speed: float = 0.6,
        turn_noise: float = 0.25,
        persistence: float = 0.9,
    ) -> None:
        super().__init__(action_space, seed)
        check_command("RandomWalk speed", speed)
        if not 0.0 <= persistence < 1.0:
            raise ValueError(f"RandomWalk persistence must be in [0, 1), got {persistence}")
        self.speed = speed
        self.turn_noise = turn_noise
        self.persistence = persistence
        self._turn = 0.0

    def reset(self, seed: int | None = None) -> None:
        super().reset(seed)
        self._turn = 0.0

    def _act(self, observation: Observation) -> NDArray[np.float64]:
        self._turn = float(np.clip(self.persistence * self._turn + self.rng.normal(0.0, self.turn_noise), -1.0, 1.0))
        return np.array([self.speed, self._turn])


class SpinInPlace(FixedPolicy):
    """Turn on the spot at a fixed rate (the cheapest way to look around)."""

    def __init__(self, action_space: spaces.Box, seed: int | None = None, turn: float = 0.5) -> None:
        super().__init__(action_space, seed)
        check_command("SpinInPlace turn", turn)
        self.turn = turn

    def _act(self, observation: Observation) -> NDArray[np.float64]:
        return np.array([0.0, self.turn])


class PatrolPath(FixedPolicy):
    """Open-loop actions ``(n, 2)`` played in order and repeated forever.

    Open loop is enough in simulation: the body moves exactly as commanded unless something
    pushes it, and a pushed robot should not be steered back by knowledge it does not have.
    """

    def __init__(self, action_space: spaces.Box, actions: ArrayLike, seed: int | None = None) -> None:
        super().__init__(action_space, seed)
        a = np.asarray(actions, dtype=np.float64)
        if a.ndim != 2 or a.shape[1] != 2 or a.shape[0] == 0:
            raise ValueError(f"PatrolPath needs actions of shape (n, 2) with n >= 1, got shape {a.shape}")
        bad = np.flatnonzero(~np.all(np.abs(a) <= 1.0, axis=1))
        if bad.size:
            raise ValueError(f"PatrolPath action {int(bad[0])} = {a[bad[0]].tolist()} is outside [-1, 1]")
        self.actions = a
        self._t = 0

    @classmethod
    def from_segments(
        cls, action_space: spaces.Box, segments: Sequence[tuple[float, float, int]], seed: int | None = None
    ) -> PatrolPath:
        """Segments ``(speed, turn, steps)`` in action units."""
        for i, (v, w, n) in enumerate(segments):
            check_command(f"PatrolPath segment {i} speed", v)
            check_command(f"PatrolPath segment {i} turn", w)
            if int(n) != n or n < 1:
                raise ValueError(f"PatrolPath segment {i} needs a positive whole number of steps, got {n!r}")
        rows = [np.tile([v, w], (int(n), 1)) for v, w, n in segments]
        return cls(action_space, np.concatenate(rows) if rows else np.zeros((0, 2)), seed)

    @classmethod
    def exp1(cls, env: Any, speed_mps: float = 0.5, turn_rate_rps: float = 1.0) -> PatrolPath:
        """The Exp 1 path a-b-c-d-e-f-g-h-a of the candidate-set paper
        (:data:`agents.policies.paths.EXP1_VERTICES`), driven from wherever the robot starts.

        On a world smaller than the paper's 5 m x 10 m field the path is scaled down to fit
        its shorter side (the turns stay the same).
        """
        base = env.unwrapped
        vertices = np.array(list(EXP1_VERTICES.values()))
        extent = np.ptp(vertices, axis=0)
        scale = min(1.0, float(np.min(np.asarray(base.config.size_m) / (extent + 1.0))))
        commands = polygon_commands(
            [tuple(v) for v in vertices * scale],
            0.0,
            speed_mps=speed_mps * scale,
            turn_rate_rps=turn_rate_rps,
            dt_s=base.config.dt_s,
        )
        return cls(env.action_space, command_actions(commands, base.max_speed_mps, base.max_turn_rate_rps))

    def reset(self, seed: int | None = None) -> None:
        super().reset(seed)
        self._t = 0

    def _act(self, observation: Observation) -> NDArray[np.float64]:
        action = self.actions[self._t % len(self.actions)]
        self._t += 1
        return action


class StopAndGo(FixedPolicy):
    """Drive a random walk for ``go_steps``, then stand still for ``stop_steps``, and repeat."""

    def __init__(
        self, action_space: spaces.Box, seed: int | None = None, go_steps: int = 60, stop_steps: int = 30, speed: float = 0.6
    ) -> None:
        super().__init__(action_space, seed)
        if go_steps < 1 or stop_steps < 1:
            raise ValueError(f"StopAndGo needs go_steps and stop_steps >= 1, got {go_steps} and {stop_steps}")
        self.go_steps = go_steps
        self.stop_steps = stop_steps
        self.walk = RandomWalk(action_space, seed, speed=speed)
        self._t = 0

    def reset(self, seed: int | None = None) -> None:
        super().reset(seed)
        self.walk.reset(None if seed is None else seed + 1)
        self._t = 0

    def _act(self, observation: Observation) -> NDArray[np.float64]:
        phase = self._t % (self.go_steps + self.stop_steps)
        self._t += 1
        return self.walk._act(observation) if phase < self.go_steps else np.zeros(2)


class _MapPolicy(FixedPolicy):
    """A policy that plans from the localizer's estimate on the known landmark map."""

    needs_sensor = "bearing_camera"  # it reads which landmarks the camera sees now

    def __init__(
        self,
        action_space: spaces.Box,
        landmarks: LandmarkMap,
        seed: int | None = None,
        *,
        max_range_m: float = math.inf,
        fov_rad: float = 2 * math.pi,
        speed: float = 0.6,
        search_turn: float = 1.0,
        occluder_halfwidth_rad: float = 0.15,
        clearance_m: float = CLEARANCE_M,
    ) -> None:
        super().__init__(action_space, seed)
        check_command(f"{type(self).__name__} speed", speed)
        if landmarks.count == 0:
            raise ValueError(f"{type(self).__name__} needs a map with landmarks")
        self.landmarks = landmarks
        if not 0 < fov_rad <= 2 * math.pi:
            raise ValueError(f"{type(self).__name__} fov_rad must be in (0, 2 pi], got {fov_rad}")
        self.max_range_m = max_range_m
        self.fov_rad = fov_rad
        self.speed = speed
        self.occluder_halfwidth_rad = occluder_halfwidth_rad
        if not clearance_m >= 0:
            raise ValueError(f"{type(self).__name__} clearance_m must be >= 0, got {clearance_m}")
        self.clearance_m = clearance_m
        self.search = SpinInPlace(action_space, seed, turn=search_turn)

    def _estimate(self, observation: Observation) -> NDArray[np.float64] | None:
        return read_estimate(observation, self.landmarks.bounds_m, type(self).__name__)

    def expected_visible(
        self,
        pose: NDArray[np.float64],
        spots: NDArray[np.float64],
        seen_now: NDArray[np.bool_],
        headings: NDArray[np.float64] | None = None,
    ) -> NDArray[np.bool_]:
        """``(C, L)``: landmarks expected in view from positions ``spots`` ``(C, 2)``.

        In camera range, inside the camera's field of view around ``headings`` ``(C,)`` (a
        narrow camera needs them), and either seen now or seen from a direction that has
        turned by more than ``occluder_halfwidth_rad`` from the current one (whatever hides
        it now does not cover it from there). A landmark outside the field of view now is not known
        to be hidden, so it counts as seen now.
        """
        lm = self.landmarks.positions_xy_m
        offsets = lm[None, :, :] - spots[:, None, :]
        in_range = np.linalg.norm(offsets, axis=-1) <= self.max_range_m
        now_dir = np.arctan2(lm[:, 1] - pose[1], lm[:, 0] - pose[0])
        turned = np.abs(wrap_angle(np.arctan2(offsets[..., 1], offsets[..., 0]) - now_dir)) > self.occluder_halfwidth_rad
        if self.fov_rad >= 2 * math.pi:
            return in_range & (seen_now | turned)
        if headings is None:
            raise ValueError(f"{type(self).__name__}.expected_visible needs headings for a camera narrower than a full turn")
        unseen_ok = seen_now | ~in_field_of_view(pose[:2], pose[2], lm, self.fov_rad)
        return (
            in_range & (unseen_ok | turned) & in_field_of_view(spots[:, None, :], np.asarray(headings)[:, None], lm, self.fov_rad)
        )

    def blocked(self, observation: Observation, directions_rad: ArrayLike) -> NDArray[np.bool_]:
        """Which travel directions (relative to the heading) the sonar finds obstructed.

        A direction is obstructed when a sonar cone within 45 deg of it reads closer than
        ``clearance_m``. Sensors are spread evenly from the heading counter-clockwise (the
        ``sonar`` observation's layout). Without a sonar nothing is obstructed.
        """
        return sonar_blocked(observation, directions_rad, self.clearance_m)

    def _inside(self, xy: NDArray[np.float64], margin: float = 0.4) -> NDArray[np.bool_]:
        xmin, ymin, xmax, ymax = self.landmarks.bounds_m
        return (
            (xy[..., 0] > xmin + margin)
            & (xy[..., 0] < xmax - margin)
            & (xy[..., 1] > ymin + margin)
            & (xy[..., 1] < ymax - margin)
        )

    def _head_for_centre(self, observation: Observation, pose: NDArray[np.float64]) -> NDArray[np.float64]:
        """The fallback when no motion qualifies: steer toward the middle of the map."""
        centre = np.mean(np.reshape(self.landmarks.bounds_m, (2, 2)), axis=0)
        return self._steer(observation, pose, math.atan2(centre[1] - pose[1], centre[0] - pose[0]))

    def _steer(self, observation: Observation, pose: NDArray[np.float64], direction_rad: float) -> NDArray[np.float64]:
        """Turn toward ``direction_rad`` and drive forward once roughly facing it (unless the
        way ahead is obstructed)."""
        error = float(wrap_angle(direction_rad - pose[2]))
        speed = 0.0 if self.blocked(observation, 0.0) else self.speed * max(0.0, math.cos(error)) ** 2
        return np.array([speed, float(np.clip(2.0 * error, -1.0, 1.0))])


class LandmarkSeeking(_MapPolicy):
    """Head for the nearby spot from which the most landmarks are expected in view.

    From the estimated pose, ``directions`` spots at ``lookahead_m`` are scored by the
    number of landmarks expected visible there (:meth:`expected_visible`; ties: keep going
    straight); without an estimate the robot spins to find landmarks.
    """

    def __init__(
        self,
        action_space: spaces.Box,
        landmarks: LandmarkMap,
        seed: int | None = None,
        *,
        lookahead_m: float = 0.8,
        directions: int = 12,
        **kwargs: Any,
    ) -> None:
        super().__init__(action_space, landmarks, seed, **kwargs)
        self.lookahead_m = lookahead_m
        self.angles = np.linspace(-math.pi, math.pi, directions, endpoint=False)

    def _act(self, observation: Observation) -> NDArray[np.float64]:
        pose = self._estimate(observation)
        if pose is None:
            return self.search._act(observation)
        world_angles = pose[2] + self.angles
        spots = pose[:2] + self.lookahead_m * np.stack([np.cos(world_angles), np.sin(world_angles)], axis=1)
        seen_now = np.asarray(observation["landmarks"]).reshape(-1, 3)[:, 0] > 0.5
        score = self.expected_visible(pose, spots, seen_now, world_angles).sum(axis=1) + 0.01 * np.cos(
            self.angles
        )  # ties: straight
        score = np.where(self._inside(spots) & ~self.blocked(observation, self.angles), score, -np.inf)
        if not np.isfinite(score).any():
            return self._head_for_centre(observation, pose)
        return self._steer(observation, pose, float(world_angles[int(np.argmax(score))]))


class GreedyInformationGain(_MapPolicy):
    """One-step look-ahead: the motion whose end pose sees the most informative bearings.

    Candidate motions (forward speed x turn rate) are rolled ``horizon_s`` ahead from the
    estimated pose; the landmarks expected in view at each end pose come from
    :meth:`expected_visible`. The score is ``log det(J_prior + J_bearings)`` with ``J_prior`` from the estimate's
    spread and ``J_bearings`` the Fisher information of the expected bearings.
    """

    def __init__(
        self,
        action_space: spaces.Box,
        landmarks: LandmarkMap,
        seed: int | None = None,
        *,
        bearing_std_rad: float = math.radians(1.0),
        horizon_s: float = 1.0,
        speeds: Sequence[float] = (0.0, 0.5, 1.0),
        turns: Sequence[float] = (-1.0, -0.5, 0.0, 0.5, 1.0),
        max_speed_mps: float = 1.75,
        max_turn_rate_rps: float = 3.0,
        **kwargs: Any,
    ) -> None:
        super().__init__(action_space, landmarks, seed, **kwargs)
        self.bearing_std_rad = bearing_std_rad
        self.horizon_s = horizon_s
        self.candidates = np.array([(v, w) for v in speeds for w in turns], dtype=np.float64)
        self.max_speed_mps = max_speed_mps
        self.max_turn_rate_rps = max_turn_rate_rps

    def end_poses(self, pose: NDArray[np.float64]) -> NDArray[np.float64]:
        """``(C, 3)`` poses after each candidate motion held for ``horizon_s`` (exact arcs)."""
        v = self.candidates[:, 0] * self.max_speed_mps
        w = self.candidates[:, 1] * self.max_turn_rate_rps
        return arc_end_poses(pose, v, w, self.horizon_s)[:, 0]

    def _act(self, observation: Observation) -> NDArray[np.float64]:
        pose = self._estimate(observation)
        if pose is None:
            return self.search._act(observation)
        seen_now = np.asarray(observation["landmarks"]).reshape(-1, 3)[:, 0] > 0.5
        spread = observation["estimate_spread"]
        xmin, ymin, xmax, ymax = self.landmarks.bounds_m
        pos_var = max(float(spread[0]) * math.hypot(xmax - xmin, ymax - ymin), 0.05) ** 2
        head_var = max(float(spread[1]) * math.pi, 0.02) ** 2
        prior = np.diag([1.0 / pos_var, 1.0 / pos_var, 1.0 / head_var])
        lm = self.landmarks.positions_xy_m
        ends = self.end_poses(pose)
        visible = self.expected_visible(pose, ends[:, :2], seen_now, ends[:, 2])
        # a motion drives along its mid-arc heading; standing and turning is never obstructed
        obstructed = (self.candidates[:, 0] > 0) & self.blocked(observation, 0.5 * (ends[:, 2] - pose[2]))
        scores = np.full(len(ends), -np.inf)
        for i, (end, expected) in enumerate(zip(ends, visible)):
            if obstructed[i] or not self._inside(end[:2]):
                continue
            info = prior + bearing_information(end, lm[expected], self.bearing_std_rad) if expected.any() else prior
            scores[i] = np.linalg.slogdet(info)[1] + 1e-3 * self.candidates[i, 0]  # ties: keep moving
        if not np.isfinite(scores).any():
            return self._head_for_centre(observation, pose)
        return self.candidates[int(np.argmax(scores))].copy()


def make_policy(name: str, env: Any, seed: int | None = None, **kwargs: Any) -> FixedPolicy:
    """Build fixed policy ``name`` for ``env`` (the map and limits come from ``env.unwrapped``)."""
    base = env.unwrapped
    space = env.action_space
    if name not in FIXED_POLICIES:
        raise ValueError(f"unknown policy {name!r}; fixed policies: {', '.join(sorted(FIXED_POLICIES))}")
    if name == "patrol":
        return PatrolPath.exp1(env, **kwargs)
    if name == "belief_greedy":
        from agents.policies.belief_greedy import make_belief_greedy

        return make_belief_greedy(env, seed, **kwargs)
    if name in ("landmark_seeking", "greedy_info_gain"):
        cam = base.config.sensor_of_type("bearing_camera")
        assert cam is None or isinstance(cam, BearingCameraConfig)
        kwargs.setdefault("max_range_m", cam.max_range_m if cam is not None else math.inf)
        kwargs.setdefault("fov_rad", cam.fov_rad if cam is not None else 2 * math.pi)
        if name == "greedy_info_gain":
            kwargs.setdefault("max_speed_mps", base.config.robot.max_speed_mps)
            kwargs.setdefault("max_turn_rate_rps", base.config.robot.max_turn_rate_rps)
            if cam is not None:
                kwargs.setdefault("bearing_std_rad", max(cam.noise_std_rad, 1e-3))
        return FIXED_POLICIES[name](space, base.landmark_map, seed, **kwargs)
    if name == "corridor_follower":
        kwargs.setdefault("dt_s", base.config.dt_s)
        kwargs.setdefault("max_speed_mps", base.config.robot.max_speed_mps)
        kwargs.setdefault("max_turn_rate_rps", base.config.robot.max_turn_rate_rps)
        sonar = base.config.sensor_of_type("sonar")
        if sonar is not None:
            kwargs.setdefault("sonar_cone_rad", sonar.cone_rad)
        lmap = base.landmark_map
        return CorridorFollower(space, ceiling_targets(base.config, lmap.features), lmap.bounds_m, seed, **kwargs)
    if follows_routes(name):
        config = base.config
        kwargs.setdefault("dt_s", config.dt_s)
        kwargs.setdefault("max_speed_mps", config.robot.max_speed_mps)
        kwargs.setdefault("max_turn_rate_rps", config.robot.max_turn_rate_rps)
        kwargs.setdefault("robot_radius_m", config.robot.radius_m)
        sonar = config.sensor_of_type("sonar")
        if sonar is not None:
            kwargs.setdefault("sonar_cone_rad", sonar.cone_rad)
        for key, value in range_sensor_kwargs(base.sensor_metadata).items():
            kwargs.setdefault(key, value)
        lmap = base.landmark_map
        route = kwargs.pop("route", None)  # a route feature's name, or the points themselves (a task's route)
        route = route_points(config, lmap.features, route) if route is None or isinstance(route, str) else route
        return FIXED_POLICIES[name](space, route, lmap.bounds_m, seed, **kwargs)
    return FIXED_POLICIES[name](space, seed=seed, **kwargs)


def follows_routes(name: str) -> bool:
    """Whether fixed policy ``name`` is a :class:`RouteFollower` (``route_follower``, ``look_then_route``):
    it drives a route, the map's or the points it is given (``make_policy(..., route=points)``)."""
    cls = FIXED_POLICIES.get(name)
    return isinstance(cls, type) and issubclass(cls, RouteFollower)


def task_route_kwargs(name: str, points_m: Sequence[Sequence[float]]) -> dict[str, Any]:
    """:func:`make_policy`'s keywords for fixed policy ``name`` on a task whose route is ``points_m``:
    a route-following policy drives those points (``route=``) when there are any, else the map's
    route; the other policies take none (``{}``)."""
    return {"route": np.asarray(points_m, dtype=np.float64)} if follows_routes(name) and len(points_m) else {}


def ceiling_targets(world: Any, features: Mapping[str, Mapping[str, Any]]) -> list[dict[str, Any]]:
    """The targets of the ceiling a world's ceiling camera looks at (or of its one ceiling feature), from the map.

    Raises:
        ValueError: for a world without a ceiling feature, or with several and no camera naming one.
    """
    ceilings = [name for name, data in features.items() if data.get("type") == "ceiling"]
    camera = world.sensor_of_type("ceiling_camera")
    name = getattr(camera, "feature", None) if camera is not None else (ceilings[0] if len(ceilings) == 1 else None)
    if name not in ceilings:
        raise ValueError(
            f"corridor_follower drives between ceiling targets: world {world.name!r} has "
            + (f"ceiling features {', '.join(ceilings)} and no ceiling camera naming one" if ceilings else "no ceiling feature")
        )
    return list(features[name].get("targets", ()))


FIXED_POLICIES: dict[str, Any] = {
    "random_walk": RandomWalk,
    "spin": SpinInPlace,
    "stop_and_go": StopAndGo,
    "patrol": PatrolPath,
    "landmark_seeking": LandmarkSeeking,
    "greedy_info_gain": GreedyInformationGain,
    "corridor_follower": CorridorFollower,
    "route_follower": RouteFollower,
    "look_then_route": LookThenRoute,
    "belief_greedy": BeliefGreedy,
}


def register_policy(name: str, cls: type[FixedPolicy]) -> type[FixedPolicy]:
    """Add a fixed policy (a plug-in): a :class:`FixedPolicy` subclass built as ``cls(action_space, seed=seed)``.

    Its ``needs_sensor`` / ``needs_feature`` say which worlds it can drive. Registering the same
    class under its name again is a no-op.

    Raises:
        ConfigError: ``name`` is taken by another policy, or ``cls`` is not a FixedPolicy subclass.
    """
    from core.schema import ConfigError

    if not (isinstance(cls, type) and issubclass(cls, FixedPolicy)):
        raise ConfigError(f"policy {name!r} must be a FixedPolicy subclass, got {cls!r}")
    current = FIXED_POLICIES.get(name)
    if current is not None and current is not cls:
        raise ConfigError(f"policy {name!r} is already registered ({current.__module__}.{current.__qualname__})")
    FIXED_POLICIES[name] = cls
    return cls
