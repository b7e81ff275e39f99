"""What a task's policy observes: the localizer's belief and what the task needs, not the raw sensors.

:class:`TaskObservation` wraps a task (a world behind ``LocalizationObservation``) and reshapes its
observation as the task's training config says (:class:`ObservationConfig`, the config's
``observation:`` section):

- ``drop``: keys the policy does not see (the corridor's 320 x 240 ``ceiling_image``, for which
  stable-baselines3 would build a 15 M-parameter CNN; a raw 1081-beam ``lidar``; the ``stereo``
  edges). The localizer still reads them: it runs inside, before this wrapper.
- ``lidar_sectors`` > 0 adds ``lidar_summary`` ``(sectors,)``: the shortest range of the ``lidar``
  entry in each of that many equal sectors of its field of view (counter-clockwise from its first
  beam), clipped at ``lidar_clip_m`` and divided by it, so 0 is touching and 1 is free to the clip.
  It is a coarse range sensor like a sonar ring: where the crowd is, at the cost of a few numbers.
- ``waypoint`` adds ``waypoint`` ``(3,)``: the task's next route point (:class:`RouteConfig`) by
  the estimate, in the estimate's frame: the direction's ``(cos, sin)`` and the distance over
  ``waypoint_clip_m`` (clipped to 1). The next point is the first more than ``reached_m`` ahead,
  along the route, of the estimate's place on it (:class:`RouteCursor`), the last one at the end.
  All zeros without a valid estimate: the policy only knows where to go from where it believes it is.
- ``lookahead_m`` > 0 adds ``lookahead`` ``(3,)``: the point on the route ``lookahead_m`` beyond the
  estimate's place on it (the end of the route at most), in the estimate's frame, as the waypoint is
  (the distance over ``lookahead_m``, clipped to 1; all zeros without a valid estimate). It is
  ``route_follower``'s pure-pursuit point: where the next route point is far ahead (the campus's first
  leg is 57 m long), a metre off the route moves the waypoint's bearing by about a degree; it moves
  this point's by tens of degrees, so the policy can see how far it is off the route.
- ``belief_map.cells`` > 0 adds ``belief_map`` ``(heading_bins, cells, cells)``: the localizer's
  hypotheses as a normalised histogram over position and heading, centred on the estimate or over
  the world (:mod:`agents.rl.belief_map`). Training reads it with a small CNN
  (:class:`agents.rl.extractor.BeliefMapExtractor`).

Also here: :class:`RouteConfig` and :class:`RouteCursor`, the task's route, which the reward's
progress term (from the truth) shares with the waypoint (from the estimate).

Nothing here reads the truth (``info``); a test checks that no observed number equals the true pose.
With every field at its default the wrapper is not applied (the soccer tasks observe what they did).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import gymnasium as gym
import numba
import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from agents.rl.belief_map import BeliefMapConfig, belief_map
from core.geometry import polyline_point
from core.schema import ConfigError, check


@dataclass(frozen=True)
class RouteConfig:
    """A task's route: the points a robot is to drive past in order (:class:`RouteCursor`)."""

    points_m: tuple[tuple[float, float], ...] = ()  # world frame; () = the map's (:func:`task_route`)
    reached_m: float = 0.3  # a point less than this ahead along the route is passed: the waypoint moves on
    search_m: float = 5.0  # the progress is searched this far either side of the last

    def __post_init__(self) -> None:
        for name in ("reached_m", "search_m"):
            value = getattr(self, name)
            check(math.isfinite(value) and value > 0, f"route.{name} must be finite and > 0, got {value!r}")
        check(
            all(len(p) == 2 and all(math.isfinite(float(c)) for c in p) for p in self.points_m),
            f"route.points_m must be finite (x, y) pairs, got {list(self.points_m)!r}",
        )


class RouteCursor:
    """How far along a route a position is, and which route point is next.

    The progress ``s`` is the arc length from the route's start to the position's nearest point on
    it. The first position joins the route where it is nearest (as ``route_follower`` does: a start
    beside the route skips what lies behind it); later ones search only within ``search_m`` of the
    last progress, so a loop's end is not mistaken for its start and a robot pushed back loses
    progress. ``remaining_m`` is the route's length beyond ``s``; the next point is the first one
    more than ``reached_m`` ahead of ``s`` (the last one at the end). The reward's progress (from the
    truth) and the observation's waypoint (from the estimate) each keep one.
    """

    def __init__(self, points_m: NDArray[np.float64], route: RouteConfig) -> None:
        check(points_m.ndim == 2 and points_m.shape[0] >= 2 and points_m.shape[1] == 2,
              f"a route needs at least two points (x, y), got shape {points_m.shape}")  # fmt: skip
        self.points_m = points_m
        self.route = route
        self._a, edge = points_m[:-1], np.diff(points_m, axis=0)
        self._length2 = np.einsum("sk,sk->s", edge, edge)
        self._edge = edge
        self._point_s = np.concatenate([[0.0], np.cumsum(np.sqrt(self._length2))])  # arc length at each point
        self.length_m = float(self._point_s[-1])
        self.progress_m: float | None = None  # None before the route is joined

    def reset(self) -> None:
        self.progress_m = None

    def update(self, x_m: float, y_m: float) -> float:
        """Move the progress to the position ``(x_m, y_m)``; return the remaining route length (m)."""
        last = math.nan if self.progress_m is None else self.progress_m
        s = _nearest_progress(
            float(x_m), float(y_m), self._a, self._edge, self._length2, self._point_s, last, self.route.search_m
        )
        if not math.isnan(s):  # NaN: every segment's nearest point beyond the search window: stay
            self.progress_m = s
        assert self.progress_m is not None
        return self.length_m - self.progress_m

    def ahead(self, distance_m: float) -> NDArray[np.float64]:
        """The route's point ``distance_m`` along it beyond the progress (its end at most)."""
        return polyline_point(self.points_m, self._point_s, (self.progress_m or 0.0) + distance_m)

    @property
    def next_point(self) -> NDArray[np.float64]:
        """The first point more than ``reached_m`` ahead of the progress (the last one at the end)."""
        ahead = np.flatnonzero(self._point_s > (self.progress_m or 0.0) + self.route.reached_m)
        return self.points_m[ahead[0] if ahead.size else -1]


@numba.njit(cache=True)
def _nearest_progress(
    x: float, y: float, a: NDArray[np.float64], edge: NDArray[np.float64], length2: NDArray[np.float64],
    point_s: NDArray[np.float64], last: float, search_m: float,
) -> float:  # fmt: skip
    """:meth:`RouteCursor.update`'s search (called twice a step): the progress (arc length) of the point of
    the route nearest ``(x, y)``, among the segments' nearest points within ``search_m`` of ``last``
    (NaN: any segment); the first of equally near ones; NaN when none lies within the window."""
    best, best_s = math.inf, math.nan
    for k in range(a.shape[0]):
        dx, dy = x - a[k, 0], y - a[k, 1]
        t = (dx * edge[k, 0] + dy * edge[k, 1]) / (length2[k] if length2[k] > 0 else 1.0)
        t = min(max(t, 0.0), 1.0)
        s = point_s[k] + t * math.sqrt(length2[k])
        if not math.isnan(last) and not abs(s - last) <= search_m:
            continue
        d = math.hypot(a[k, 0] + t * edge[k, 0] - x, a[k, 1] + t * edge[k, 1] - y)
        if d < best:
            best, best_s = d, s
    return best_s


@dataclass(frozen=True)
class ObservationConfig:
    """How a task reshapes the observation (module docstring); the defaults change nothing."""

    drop: tuple[str, ...] = ()  # observation keys the policy does not see
    lidar_sectors: int = 0  # > 0: add lidar_summary, the least range of the lidar entry per sector
    lidar_clip_m: float = 5.0  # lidar_summary's ranges are clipped here and divided by it
    waypoint: bool = False  # add waypoint: the route's next point in the estimate's frame
    waypoint_clip_m: float = 10.0  # the waypoint's distance is divided by this, clipped to 1
    lookahead_m: float = 0.0  # > 0: add lookahead, the route's point this far ahead of the estimate's place on it
    belief_map: BeliefMapConfig = field(default_factory=BeliefMapConfig)  # cells > 0: add the belief map

    def __post_init__(self) -> None:
        check(self.lidar_sectors >= 0, f"observation.lidar_sectors must be >= 0, got {self.lidar_sectors!r}")
        for name in ("lidar_clip_m", "waypoint_clip_m"):
            value = getattr(self, name)
            check(math.isfinite(value) and value > 0, f"observation.{name} must be finite and > 0, got {value!r}")
        check(
            math.isfinite(self.lookahead_m) and self.lookahead_m >= 0,
            f"observation.lookahead_m must be finite and >= 0 (0: none), got {self.lookahead_m!r}",
        )
        check(len(set(self.drop)) == len(self.drop), f"observation.drop repeats a key: {list(self.drop)}")

    @property
    def changes_anything(self) -> bool:
        return bool(self.drop) or self.lidar_sectors > 0 or self.waypoint or self.lookahead_m > 0 or self.belief_map.cells > 0


def task_route(base: Any, route: RouteConfig) -> NDArray[np.float64] | None:
    """A task's route points ``(V, 2)`` (world frame, m): ``route.points_m`` when given, else the
    points of the map's one route feature, else the targets of its one ceiling feature in the map's
    order (the order a robot drives under them); None when there is none of these.

    ``base``: the unwrapped env (its ``landmark_map``).
    """
    if route.points_m:
        return np.asarray(route.points_m, dtype=np.float64)
    features = base.landmark_map.features
    for kind, points in (("route", lambda f: f["points_m"]), ("ceiling", lambda f: [(t["x_m"], t["y_m"]) for t in f["targets"]])):
        found = [data for data in features.values() if data.get("type") == kind]
        if len(found) == 1:
            return np.asarray(points(found[0]), dtype=np.float64).reshape(-1, 2)
    return None


def route_cursor(base: Any, route: RouteConfig, who: str) -> RouteCursor:
    """A :class:`RouteCursor` on the task's route (:func:`task_route`).

    Raises:
        ConfigError: naming ``who`` needs it, when the task has no route.
    """
    points = task_route(base, route)
    if points is None:
        raise ConfigError(
            f"{who} needs a route: world {base.config.name!r} has no route feature and no ceiling targets in its map "
            "(give the task's route.points_m)"
        )
    return RouteCursor(points, route)


class TaskObservation(gym.ObservationWrapper[dict[str, Any], Any, dict[str, Any]], gym.utils.RecordConstructorArgs):
    """Reshape a task's observation as ``config`` says (module docstring).

    Args:
        env: a crowdloc env behind ``LocalizationObservation`` (its ``estimate`` entry).
        config: :class:`ObservationConfig`.
        route: the task's route (for the waypoint).

    Raises:
        ConfigError: naming a dropped key the observation lacks, a LIDAR summary without a
            ``lidar`` entry, or a waypoint without a route.
    """

    def __init__(self, env: gym.Env[Any, Any], config: ObservationConfig, route: RouteConfig | None = None) -> None:
        gym.utils.RecordConstructorArgs.__init__(self, config=config, route=route)
        gym.ObservationWrapper.__init__(self, env)
        self.config = config
        space = env.observation_space
        assert isinstance(space, spaces.Dict)
        base: Any = env.unwrapped
        missing = [key for key in config.drop if key not in space.spaces]
        if missing:
            raise ConfigError(f"observation.drop: {missing} not in the observation (keys: {', '.join(space.spaces)})")
        kept = {key: sub for key, sub in space.spaces.items() if key not in config.drop}
        self._sector_of: NDArray[np.intp] | None = None
        if config.lidar_sectors:
            if "lidar" not in space.spaces:
                raise ConfigError(f"observation.lidar_sectors = {config.lidar_sectors} needs a lidar entry; world "
                                  f"{base.config.name!r} observes {', '.join(space.spaces)}")  # fmt: skip
            beams = int(np.prod(space.spaces["lidar"].shape or (0,)))
            check(
                config.lidar_sectors <= beams, f"observation.lidar_sectors = {config.lidar_sectors} > the LIDAR's {beams} beams"
            )
            self._sector_of = (np.arange(beams) * config.lidar_sectors) // beams
            kept["lidar_summary"] = spaces.Box(0.0, 1.0, (config.lidar_sectors,), np.float32)
        self._cursor: RouteCursor | None = None
        #: the route entries observed -> the distance their third number is over
        self._route_scales = {key: scale for key, wanted, scale in (("waypoint", config.waypoint, config.waypoint_clip_m),
                              ("lookahead", config.lookahead_m > 0, config.lookahead_m)) if wanted}  # fmt: skip
        for key in self._route_scales:
            if "estimate" not in space.spaces:
                raise ConfigError(f"observation.{key} is in the estimate's frame: make the env with localizer=...")
            if self._cursor is None:
                self._cursor = route_cursor(base, route or RouteConfig(), f"observation.{key}")
            kept[key] = spaces.Box(-1.0, 1.0, (3,), np.float32)
        self._bounds_m: tuple[float, float, float, float] | None = None
        if config.belief_map.cells:
            if "estimate" not in space.spaces:
                raise ConfigError("observation.belief_map is the localizer's belief: make the env with localizer=...")
            self._bounds_m = tuple(float(b) for b in base.landmark_map.bounds_m)  # type: ignore[assignment]
            kept["belief_map"] = spaces.Box(0.0, 1.0, config.belief_map.shape, np.float32)
        self.observation_space = spaces.Dict(kept)

    def observation(self, observation: dict[str, Any]) -> dict[str, Any]:
        out = {key: value for key, value in observation.items() if key not in self.config.drop}
        if self._sector_of is not None:
            ranges = np.minimum(np.asarray(observation["lidar"], dtype=np.float64), self.config.lidar_clip_m)
            least = np.full(self.config.lidar_sectors, self.config.lidar_clip_m)
            np.minimum.at(least, self._sector_of, ranges)
            out["lidar_summary"] = (least / self.config.lidar_clip_m).astype(np.float32)
        if self._cursor is not None:
            out.update(self._route_points())
        if self._bounds_m is not None:
            localizer = self.env.get_wrapper_attr("localizer")
            estimate = self.env.get_wrapper_attr("estimate")
            out["belief_map"] = belief_map(self.config.belief_map, localizer.overlay(), estimate, self._bounds_m)
        return out

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[dict[str, Any], dict[str, Any]]:
        if self._cursor is not None:
            self._cursor.reset()
        return super().reset(seed=seed, options=options)

    def _route_points(self) -> dict[str, NDArray[np.float32]]:
        """The ``waypoint`` and ``lookahead`` entries the config asks for (module docstring)."""
        assert self._cursor is not None
        out = {key: np.zeros(3, dtype=np.float32) for key in self._route_scales}
        est = self.env.get_wrapper_attr("estimate")
        if not est.valid:
            return out
        self._cursor.update(est.x_m, est.y_m)
        for key, scale in self._route_scales.items():
            point = self._cursor.next_point if key == "waypoint" else self._cursor.ahead(self.config.lookahead_m)
            dx, dy = point[0] - est.x_m, point[1] - est.y_m
            bearing = math.atan2(dy, dx) - est.theta_rad
            out[key][:] = (math.cos(bearing), math.sin(bearing), min(math.hypot(dx, dy) / scale, 1.0))
        return out
