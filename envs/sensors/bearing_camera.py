"""Bearing camera: the bearing of each landmark whose line of sight is clear.

Omnidirectional (the papers' robots) or, with ``fov_rad`` below a full turn, a forward
camera that must be turned toward landmarks.

The camera finds landmarks by colour, so it can be fooled in two ways:

- *random false detections* (``false_detection_probability``): per slot and frame, a
  uniformly random bearing with ``visible = 1``; noise, flagged in ``info["false_detections"]``;
- *persistent false detections* (``distractors``): objects of a landmark's colour at fixed
  places beyond the field (the candidate-set paper's "blue or yellow objects outside the
  field" seen by the omnidirectional camera). In a frame where landmark k's slot would be
  empty because the real landmark is occluded, out of range or outside the field of view,
  and a distractor of k is in view, the slot reports the distractor's bearing, so a
  filter sees the same wrong bearing frame after frame; flagged in
  ``info["distractor_detections"]``. See :class:`DistractorConfig` for the rules.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar

import numba
import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from core.geometry import in_field_of_view
from core.raycast import sight_lines_clear
from core.schema import check
from envs.palette import landmark_color
from envs.sensors.base import SensorBase, SensorConfig, register_sensor
from envs.state import WorldState

if TYPE_CHECKING:
    from envs.config import WorldConfig

SIGHT_LINE = (255, 255, 160)
DISTRACTOR_SIGHT_LINE = (255, 120, 60)  # a sight line to a distractor reported in a landmark's slot
_DISTRACTOR_MIN_PX = 6  # distractor rings are at least this radius so that they show


@dataclass(frozen=True)
class DistractorConfig:
    """An object beyond the field that the camera takes for landmark ``landmark`` (a persistent false detection).

    The candidate-set paper's camera identifies the goals and corner poles by their blue and
    yellow paint; blue or yellow things outside the field that show in the omnidirectional
    image are taken for landmarks. A distractor is such a thing at a fixed place:

    - it is reported in ``landmark``'s slot only in a frame where that slot would otherwise
      be empty: the real landmark wins when both are in view (the issue's "whenever they are
      in view and the real landmark is not");
    - "in view": a clear line of sight from the robot to the near side of its disc (radius
      ``radius_m``; the imitated landmark's radius when None) against the same walls and crowd
      members that hide landmarks, inside the camera's field of view and within the camera's
      ``max_range_m`` and the distractor's own ``max_range_m``. The imitated landmark's own
      ``max_range_m`` does not apply: it says how far that pole (a small one) can be made
      out, and a distractor is another object of its own size;
    - when several distractors of one landmark are in view, the nearest (centre distance) is reported;
    - dropout drops the slot, whichever object would have filled it (a missed detection, or
      the candidate-set paper's Exp 2 using a random subset of the landmarks: a dropped
      landmark is not replaced by its distractor), and a random false detection in the slot
      takes precedence over everything;
    - the reported bearing carries the camera's bearing noise (the slot's own noise draw:
      distractors draw no random numbers);
    - it is not a body: it neither collides nor hides anything.

    Where: the centre must lie outside the field (``size_m`` from ``origin_m``, edges
    included: the paper's objects are beyond it; an object inside would be something robots
    drive through) and strictly inside the boundary walls (``boundary_margin_m`` around the
    field): the robot never leaves the walls and they hide whatever stands behind them, so a
    distractor beyond them could never be seen. A world without a margin therefore has no
    room for distractors.

    Attributes:
        landmark: name of the landmark it looks like (one of the world's ``landmarks``).
        x_m, y_m: centre in the world frame, metres.
        radius_m: disc radius in metres; None: the imitated landmark's ``radius_m``.
        max_range_m: beyond this distance (metres) the camera does not see it (on top of the camera's ``max_range_m``).
    """

    #: the fields that may be ``inf`` (:func:`envs.config.non_finite_numbers`): no range limit
    unbounded_fields: ClassVar[frozenset[str]] = frozenset({"max_range_m"})

    landmark: str
    x_m: float
    y_m: float
    radius_m: float | None = None
    max_range_m: float = math.inf

    def __post_init__(self) -> None:
        where = f"distractor of {self.landmark!r} at ({self.x_m!r}, {self.y_m!r})"
        check(
            math.isfinite(self.x_m) and math.isfinite(self.y_m),
            f"{where}: x_m and y_m must be finite, got ({self.x_m}, {self.y_m})",
        )
        if self.radius_m is not None:
            check(
                0 < self.radius_m < math.inf,
                f"{where}: radius_m must be > 0 and finite, got {self.radius_m}",
            )
        check(self.max_range_m > 0, f"{where}: max_range_m must be > 0, got {self.max_range_m}")


@dataclass(frozen=True)
class BearingCameraConfig(SensorConfig):
    """Camera reporting landmark bearings: omnidirectional or, with ``fov_rad`` below a full
    turn, forward-looking.

    ``distractors`` (persistent false detections, :class:`DistractorConfig`) belong to the
    camera, not to the world: they are things only a colour camera takes for landmarks (the
    LIDAR and the sonar see no colour, and they are not bodies: nothing collides with them or
    is hidden by them), and a camera with other colour thresholds would be fooled by other
    things. Their landmark names and places are checked against the world in
    :meth:`check_world`. None by default.
    """

    #: the fields that may be ``inf`` (:func:`envs.config.non_finite_numbers`): a bearing has no range limit
    unbounded_fields: ClassVar[frozenset[str]] = frozenset({"max_range_m"})

    key: str = "landmarks"
    noise_std_rad: float = math.radians(1.0)
    max_range_m: float = math.inf  # applies to every landmark on top of its own max_range_m
    fov_rad: float = 2 * math.pi  # horizontal field of view centred on the robot's heading
    dropout_probability: float = 0.0  # a visible landmark is missed in a frame
    false_detection_probability: float = 0.0  # per slot and frame: a wrong bearing is reported
    height_m: float = 0.6  # the lens's height: bodies block a sight line where they reach above it
    distractors: tuple[DistractorConfig, ...] = ()  # persistent false detections at fixed places beyond the field

    def __post_init__(self) -> None:
        check(self.noise_std_rad >= 0, f"camera.noise_std_rad must be >= 0, got {self.noise_std_rad}")
        check(self.max_range_m > 0, f"camera.max_range_m must be > 0, got {self.max_range_m}")
        check(0 < self.fov_rad <= 2 * math.pi, f"camera.fov_rad must be in (0, 2 pi], got {self.fov_rad}")
        check(0 <= self.dropout_probability <= 1, f"camera.dropout_probability must be in [0, 1], got {self.dropout_probability}")
        check(
            0 <= self.false_detection_probability <= 1,
            f"camera.false_detection_probability must be in [0, 1], got {self.false_detection_probability}",
        )
        check(
            math.isfinite(self.height_m) and self.height_m >= 0, f"camera.height_m must be finite and >= 0, got {self.height_m}"
        )
        for d in self.distractors:
            check(
                isinstance(d, DistractorConfig),
                f"camera.distractors: expected DistractorConfig entries, got {type(d).__name__} {d!r}",
            )
        object.__setattr__(self, "distractors", tuple(self.distractors))  # a copy: the caller's list may change

    def check_world(self, world: WorldConfig, name: str) -> None:
        check(len(world.landmarks) > 0, f"world {world.name!r}: the bearing camera {name!r} needs landmarks")
        names = [lm.name for lm in world.landmarks]
        fx0, fy0, fx1, fy1 = world.field_m
        ax0, ay0, ax1, ay1 = world.arena_m
        for i, d in enumerate(self.distractors):
            where = f"world {world.name!r}: camera {name!r}: distractors[{i}]"
            check(
                d.landmark in names,
                f"{where}: unknown landmark {d.landmark!r} (the world's landmarks: {', '.join(names)})",
            )
            check(
                not (fx0 <= d.x_m <= fx1 and fy0 <= d.y_m <= fy1),
                f"{where}: ({d.x_m:g}, {d.y_m:g}) m is inside the field x in [{fx0:g}, {fx1:g}], y in [{fy0:g}, {fy1:g}]; "
                "a distractor stands beyond the field",
            )
            check(
                ax0 < d.x_m < ax1 and ay0 < d.y_m < ay1,
                f"{where}: ({d.x_m:g}, {d.y_m:g}) m is not inside the boundary walls x in ({ax0:g}, {ax1:g}), "
                f"y in ({ay0:g}, {ay1:g}) (the field and its boundary_margin_m = {world.boundary_margin_m:g} m); "
                "the walls would always hide it",
            )


@register_sensor("bearing_camera", BearingCameraConfig)
class BearingCamera(SensorBase):
    """A bearing per landmark whose line of sight is clear, within range and, for a camera
    narrower than a full turn, inside the field of view around the heading.

    Observation ``(3 L,)``: for each landmark slot in turn ``(visible, cos(bearing),
    sin(bearing))`` in the robot frame (a flat vector, as stable-baselines3 expects; reshape
    to ``(L, 3)`` to read it), zeros when not detected. A false detection puts a uniformly
    random bearing in a slot with ``visible = 1``; a distractor in view (see
    :class:`DistractorConfig`) puts its own bearing, with the bearing noise, in the slot of
    the landmark it imitates when that landmark is not detected. ``info`` gets
    ``visible_landmarks``, ``false_detections`` and ``distractor_detections``: ``(L,)`` flags
    of the landmarks truly in sight (before dropout), of the slots holding a random false
    detection and of the slots holding a distractor's bearing (never both: a random false
    detection takes the slot first). A slot that is flagged in neither of the last two and
    reads ``visible = 1`` holds the real landmark.
    """

    draw_layer = "under"

    def __init__(self, name: str, config: BearingCameraConfig, world: WorldConfig, state: WorldState) -> None:
        self.name = name
        self.key = config.key
        self.config = config
        self.count = state.landmark_xy.shape[0]
        self.max_range_m = np.minimum(state.landmark_max_range_m, config.max_range_m)
        seen = state.walls_at(config.height_m)
        self._seg_a, self._seg_b = state.seg_a[seen], state.seg_b[seen]
        slot = {n: j for j, n in enumerate(state.landmark_names)}
        ds = config.distractors
        #: ``(D,)`` the landmark slot each distractor imitates; ``(D, 2)`` centres, ``(D,)`` radii and ranges
        self.distractor_slot = np.array([slot[d.landmark] for d in ds], dtype=np.int64)
        self.distractor_xy = np.array([(d.x_m, d.y_m) for d in ds], dtype=np.float64).reshape(-1, 2)
        self.distractor_radius_m = np.array(
            [state.landmark_radius_m[slot[d.landmark]] if d.radius_m is None else d.radius_m for d in ds], dtype=np.float64
        )
        self.distractor_max_range_m = np.array([min(d.max_range_m, config.max_range_m) for d in ds], dtype=np.float64)
        # the landmarks, then the distractors: one sight-line test a frame for both
        self._targets_xy = np.vstack([state.landmark_xy, self.distractor_xy])
        self._targets_radius_m = np.concatenate([state.landmark_radius_m, self.distractor_radius_m])
        self._targets_max_range_m = np.concatenate([self.max_range_m, self.distractor_max_range_m])
        self._narrow = config.fov_rad < 2 * math.pi  # a forward camera: the field of view limits it too
        self._everywhere = np.ones(self._targets_xy.shape[0], dtype=np.bool_)  # an omnidirectional camera's field of view
        self._everywhere.setflags(write=False)

    def space(self) -> spaces.Box:
        return spaces.Box(-1.0, 1.0, shape=(3 * self.count,), dtype=np.float32)

    def metadata(self) -> dict[str, Any]:
        return {"landmark_count": self.count, "noise_std_rad": self.config.noise_std_rad, "fov_rad": self.config.fov_rad}

    def true_visibility(self, state: WorldState) -> NDArray[np.bool_]:
        """``(L,)`` landmarks in the field of view whose line of sight is clear and within range (no dropout)."""
        return self._views(state)[: self.count]

    def distractors_in_view(self, state: WorldState) -> NDArray[np.bool_]:
        """``(D,)`` distractors the camera would see now (in config order), whether or not their landmark is in view."""
        return self._views(state)[self.count :]

    def _views(self, state: WorldState) -> NDArray[np.bool_]:
        """``(L + D,)`` the landmarks, then the distractors, with a clear line of sight, within
        range and inside the field of view, in one test (:meth:`observe` makes the same test
        inside its kernel).

        A sight line is blocked by the walls and by the bodies' sections at the camera's
        height (a person's torso, a robot's body, a car; not a ball below the lens).
        """
        occluders = state.occluders(self.config.height_m)
        seg_a, seg_b = occluders.walls(self._seg_a, self._seg_b)  # with the sides of a car's body
        origin = state.positions[0]
        xy = self._targets_xy
        clear = sight_lines_clear(
            origin, xy, self._targets_radius_m, self._targets_max_range_m, seg_a, seg_b, occluders.centres, occluders.radii
        )
        if self._narrow:
            clear &= in_field_of_view(origin, state.angles[0], xy, self.config.fov_rad)
        return clear

    def observe(self, state: WorldState, rng: np.random.Generator) -> tuple[NDArray[np.float32], dict[str, Any]]:
        cfg = self.config
        draws = rng.random((3, self.count))  # dropout, false detection, false bearing
        z = rng.standard_normal((self.count,))  # the bearing noise in units of noise_std_rad
        # the sight-line test of _views and the slots in one kernel call: a call from Python
        # costs about as much as the work of a frame
        origin, heading = state.positions[0], state.angles[0]
        occluders = state.occluders(cfg.height_m)
        seg_a, seg_b = occluders.walls(self._seg_a, self._seg_b)  # with the sides of a car's body
        in_fov = in_field_of_view(origin, heading, self._targets_xy, cfg.fov_rad) if self._narrow else self._everywhere
        obs, marks = _camera_frame(
            origin,
            heading,
            self._targets_xy,
            self._targets_radius_m,
            self._targets_max_range_m,
            seg_a,
            seg_b,
            occluders.centres,
            occluders.radii,
            in_fov,
            self.distractor_slot,
            draws,
            z,
            cfg.noise_std_rad,
            cfg.dropout_probability,
            cfg.false_detection_probability,
        )
        # fixed shapes (one flag per landmark), so that vector envs can stack the infos
        return obs, {"visible_landmarks": marks[0], "false_detections": marks[1], "distractor_detections": marks[2]}

    def draw(self, canvas: Any, state: WorldState, reading: NDArray[np.float32], info: Mapping[str, Any]) -> None:
        """Sight lines to the landmarks truly in view and to the distractors reported, the
        distractors (hollow rings in the colour of the landmark they imitate, a dot in the
        middle) and, for a narrow camera, the edges of its view."""
        pose = state.robot_pose
        for j in np.flatnonzero(info.get("visible_landmarks", ())):
            canvas.line(pose[:2], state.landmark_xy[j], SIGHT_LINE, 1)
        if self.distractor_slot.size:
            reported = np.asarray(info.get("distractor_detections", np.zeros(self.count, dtype=bool)), dtype=bool)
            chosen = _nearest_in_view(
                state.positions[0], self.distractor_xy, self.distractor_slot, self.distractors_in_view(state), self.count
            )
            for j in np.flatnonzero(reported & (chosen >= 0)):
                canvas.line(pose[:2], self.distractor_xy[chosen[j]], DISTRACTOR_SIGHT_LINE, 1)
            for (x, y), r, j in zip(self.distractor_xy, self.distractor_radius_m, self.distractor_slot):
                color = landmark_color(int(j))
                ring_m = max(float(r), _DISTRACTOR_MIN_PX / canvas.scale)
                canvas.circle(x, y, ring_m, color, 2)
                canvas.circle(x, y, 1.5 / canvas.scale, color, 0)
        fov = self.config.fov_rad
        if fov < 2 * np.pi:
            reach = float(np.hypot(*np.ptp(state.seg_a, axis=0))) if len(state.seg_a) else 10.0
            for side in (-0.5, 0.5):
                edge = pose[2] + side * fov
                canvas.line(pose[:2], pose[:2] + reach * np.array([np.cos(edge), np.sin(edge)]), SIGHT_LINE, 1)


@numba.njit(cache=True)
def _nearest_in_view(
    origin: NDArray[np.float64],
    distractor_xy: NDArray[np.float64],
    distractor_slot: NDArray[np.int64],
    in_view: NDArray[np.bool_],
    count: int,
) -> NDArray[np.int64]:
    """``(L,)`` per landmark slot the nearest distractor in view (its row), -1 for none."""
    best = np.full(count, -1, dtype=np.int64)
    best_d2 = np.full(count, math.inf)
    for d in range(distractor_xy.shape[0]):
        if not in_view[d]:
            continue
        dx = distractor_xy[d, 0] - origin[0]
        dy = distractor_xy[d, 1] - origin[1]
        d2 = dx * dx + dy * dy
        j = distractor_slot[d]
        if d2 < best_d2[j]:
            best_d2[j] = d2
            best[j] = d
    return best


@numba.njit(cache=True)
def _camera_frame(
    origin: NDArray[np.float64],
    heading: float,
    targets_xy: NDArray[np.float64],
    targets_radius_m: NDArray[np.float64],
    targets_max_range_m: NDArray[np.float64],
    seg_a: NDArray[np.float64],
    seg_b: NDArray[np.float64],
    centres: NDArray[np.float64],
    radii: NDArray[np.float64],
    in_fov: NDArray[np.bool_],
    distractor_slot: NDArray[np.int64],
    draws: NDArray[np.float64],
    z: NDArray[np.float64],
    noise_std: float,
    dropout: float,
    false_rate: float,
) -> tuple[NDArray[np.float32], NDArray[np.bool_]]:
    """One frame: the flat ``(3 L,)`` observation and ``(3, L)`` marks per slot: the landmark
    in view (before dropout), a random false detection, a distractor reported.

    ``targets_xy`` (radii, ranges) holds the ``L`` landmarks, then the distractors; a target is
    in view where its sight line is clear of the walls ``seg_a``-``seg_b`` and the discs
    ``centres``, ``radii`` (:func:`~core.raycast.sight_lines_clear`) and ``in_fov`` holds.
    Per slot, first match wins: a random false detection; nothing when the slot drops out (a
    missed detection drops the slot, whichever object would have filled it); the landmark
    when visible; the nearest distractor in view of that landmark; else the slot stays zero.
    A bearing carries the noise ``z noise_std``.
    """
    in_view = sight_lines_clear(origin, targets_xy, targets_radius_m, targets_max_range_m, seg_a, seg_b, centres, radii)
    in_view &= in_fov
    n = draws.shape[1]
    obs = np.zeros(3 * n, dtype=np.float32)
    marks = np.zeros((3, n), dtype=np.bool_)  # one array to hand back: in view, false detections, distractors
    marks[0] = in_view[:n]
    distractors = distractor_slot.shape[0] > 0
    if distractors:
        nearest = _nearest_in_view(origin, targets_xy[n:], distractor_slot, in_view[n:], n)
    else:  # no distractors: nothing to look for
        nearest = distractor_slot
    for j in range(n):
        if draws[1, j] < false_rate:
            marks[1, j] = True
            bearing = (draws[2, j] * 2.0 - 1.0) * math.pi
        elif draws[0, j] < dropout:
            continue
        elif in_view[j]:
            bearing = math.atan2(targets_xy[j, 1] - origin[1], targets_xy[j, 0] - origin[0]) - heading + z[j] * noise_std
        elif distractors and nearest[j] >= 0:
            d = n + nearest[j]
            marks[2, j] = True
            bearing = math.atan2(targets_xy[d, 1] - origin[1], targets_xy[d, 0] - origin[0]) - heading + z[j] * noise_std
        else:
            continue
        obs[3 * j] = 1.0
        obs[3 * j + 1] = math.cos(bearing)
        obs[3 * j + 2] = math.sin(bearing)
    return obs, marks
