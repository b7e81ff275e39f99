"""Seeded layouts: a world's static scenery drawn from a generator, one layout per seed.

A policy trained and tested on one map can learn that map instead of how to localize. A layout
generator draws the parts of a world a localizer's map holds (where the landmarks stand, what
misleads the camera) from a seed, so that a task can train on some layouts and be tested on
others it never saw. Every number a layout does not vary stays the world's own, and without a
layout (``layout=None``, the default) a world is exactly its YAML: every reproduction and the
benchmark run the papers' layouts.

``gym.make(id, layout=N)`` (or ``LocalizationEnv(..., layout=N)``) builds layout ``N`` of the
world, before the keyword overrides (which apply on top). A layout is a function of its seed
alone (:data:`LAYOUT_STREAM` keeps its draws apart from every episode's), so layout ``N`` is the
same in every process, task and crowd.

Generators (:func:`register_layout` adds one; :func:`layout_worlds` lists them):

- ``robocup_crowded`` (:func:`soccer_field_layout`): the field's size, its eight landmarks'
  kinds, names and radii, the number of distractors and everything that moves stay the paper's.
  Varied: the goals' width (both alike, 1.5-2.5 m; the paper's is 2 m) and where each goal sits
  on its end line (each on its own, at least 0.75 m from the corners); each corner pole moved
  0-1 m along its side line, away from its corner; each distractor the likeness of a random
  landmark, standing as the paper's do by the one it imitates: beyond a field line that landmark
  stands on, 0.2-0.4 m out, 0.3-1 m along the line from it, of radius 0.1-0.15 m (a likeness
  of a post behind the far goal would report bearings no real field gives: the paper's
  false detections are things of a landmark's colour near it). The goalkeeper keeps the goal on
  the far end line (``keeper_posts``).
- ``ceiling_corridor`` (:func:`corridor_layout`): the field, the straight walls at the corridor
  crowd's ``centre_x_m +- half_width_m``, the robot, its start under the first target, the last
  target and the goal under it (the drive's length), the targets' colour codes, the sensors and the
  crowd stay the paper's. Varied, on each side: 2-3 door recesses (0.9 m wide, 0.25 m deep) and 1-2
  alcoves (1.6-2.4 m long, back to the field's edge) at random places, at least 0.5 m of wall
  between two and from the field's ends; each target between the first and the last moved up to
  1 m along the corridor; each exit sign beside a random one of those targets, 0.3-0.8 m before or
  after it, on a random side; the light panels' pitch (1.8-3.0 m), the sprinklers' (3.0-4.2 m),
  where each row starts, and the tile grid's origin. The standing groups find their places by the
  walls of the layout.
- ``crowded_room`` (:func:`room_layout`): the queues, the bevelled corner, the door and where each
  piece of furniture stands, placed on an occupancy grid so that each keeps clear of the others,
  the queues' places and walks, and the middle (docs/environments.md#layouts gives the bounds).
- ``stereo_campus`` (:func:`campus_layout`): the campus, its road, lanes, walkways, parking strip,
  route, goal, robot, sensors and crowd stay the paper's. Varied: each building's footprint moved in
  from each side of its box by up to 3 m (at most a fifth of its size; the same shape on the smaller
  box, its doors on the same sides), its height (8-22 m, the paper's range), the façades shuffled
  among the buildings with their horizontal sizes scaled alike by 0.8-1.25, and each lamp, pole and
  tree moved up to 4 m along the path it lines to a place clear of the paths, buildings, parked cars
  and the fence. Its scene map is a drive on the layout (``agents.experiments.scene_maps``).
"""

from __future__ import annotations

import dataclasses
import numbers
from collections.abc import Callable
from typing import Any

import numpy as np

from core.schema import ConfigError, replace_checked
from envs.config import LandmarkConfig, WorldConfig
from envs.sensors.bearing_camera import BearingCameraConfig

#: the first word of every layout's seed sequence: no episode, crowd or sensor draws from it
LAYOUT_STREAM = 0x1A70

Generator = Callable[[WorldConfig, np.random.Generator], dict[str, Any]]
_GENERATORS: dict[str, Generator] = {}


def register_layout(world: str, generator: Generator) -> None:
    """Make ``generator(config, rng) -> overrides`` the layout generator of the world named ``world``.

    The overrides are a mapping of :class:`WorldConfig` fields, applied with the world's checks
    (``landmarks``, ``sensors``, ``crowds``, ...)."""
    _GENERATORS[world] = generator


def layout_worlds() -> tuple[str, ...]:
    """The names of the worlds that have a layout generator."""
    return tuple(sorted(_GENERATORS))


def checked_layout(layout: object, where: str = "layout") -> int:
    """``layout`` as a seed (an int >= 0, not a bool), or a :class:`ConfigError` naming it."""
    if isinstance(layout, bool) or not isinstance(layout, numbers.Integral) or int(layout) < 0:
        raise ConfigError(f"{where} must be a layout seed, an integer >= 0, got {layout!r}")
    return int(layout)


def layout_world(config: WorldConfig, layout: int) -> WorldConfig:
    """World ``config`` with layout ``layout`` drawn by its world's generator.

    Raises:
        ConfigError: for a bad seed, or a world without a generator (naming those that have one).
    """
    seed = checked_layout(layout)
    generator = _GENERATORS.get(config.name)
    if generator is None:
        raise ConfigError(
            f"layout={seed}: world {config.name!r} has no layout generator "
            f"(worlds with one: {', '.join(layout_worlds()) or 'none'})"
        )
    rng = np.random.default_rng(np.random.SeedSequence([LAYOUT_STREAM, seed]))
    return replace_checked(config, generator(config, rng), where=f"layout {seed} of world {config.name!r}")


# ------------------------------------------------------------------------------------- soccer field

#: the goals' width, m (both goals alike; the paper's field: 2 m)
GOAL_WIDTH_M = (1.5, 2.5)
#: the least distance from a goal post to the field's corner along the end line, m
POST_FROM_CORNER_M = 0.75
#: how far a corner pole moves along its side line, away from its corner, m
CORNER_SHIFT_M = (0.0, 1.0)
#: a distractor's distance beyond the field's line, m, and its radius, m
DISTRACTOR_OUT_M = (0.2, 0.4)
DISTRACTOR_RADIUS_M = (0.1, 0.15)
#: a distractor's distance along the field line from the landmark it imitates, m (the paper's field: 0.4 to 0.8)
DISTRACTOR_ALONG_M = (0.3, 1.0)


def _soccer_parts(config: WorldConfig) -> tuple[tuple[float, float, float, float], list[LandmarkConfig], list[LandmarkConfig]]:
    """The field's box (the landmarks' extent), its corner poles and its goal posts, or a ConfigError."""
    xs = [lm.x_m for lm in config.landmarks]
    ys = [lm.y_m for lm in config.landmarks]
    box = (min(xs), min(ys), max(xs), max(ys))
    corners = [lm for lm in config.landmarks if lm.x_m in (box[0], box[2]) and lm.y_m in (box[1], box[3])]
    posts = [lm for lm in config.landmarks if lm not in corners and lm.y_m in (box[1], box[3])]
    if len(corners) != 4 or len(posts) != 4 or len(config.landmarks) != 8:
        raise ConfigError(
            f"world {config.name!r}: the soccer layout needs 4 corner poles and 2 goals of 2 posts on the end lines "
            f"(y = {box[1]:g} and y = {box[3]:g}), got landmarks {[lm.name for lm in config.landmarks]}"
        )
    return box, corners, posts


def soccer_field_layout(config: WorldConfig, rng: np.random.Generator) -> dict[str, Any]:
    """A soccer field's layout: the goals' width and places, the corner poles, the distractors (module docstring)."""
    (x0, y0, x1, y1), corners, posts = _soccer_parts(config)
    width = float(rng.uniform(*GOAL_WIDTH_M))
    lo, hi = x0 + POST_FROM_CORNER_M + width / 2, x1 - POST_FROM_CORNER_M - width / 2
    if lo > hi:
        raise ConfigError(f"world {config.name!r}: a {width:.2f} m goal does not fit on a {x1 - x0:g} m end line")
    centres = {y0: float(rng.uniform(lo, hi)), y1: float(rng.uniform(lo, hi))}
    moved: dict[str, tuple[float, float]] = {}
    for line in (y0, y1):
        ends = sorted((lm for lm in posts if lm.y_m == line), key=lambda lm: lm.x_m)
        moved[ends[0].name] = (centres[line] - width / 2, line)
        moved[ends[1].name] = (centres[line] + width / 2, line)
    for lm in corners:
        shift = float(rng.uniform(*CORNER_SHIFT_M))
        moved[lm.name] = (lm.x_m, lm.y_m + shift if lm.y_m == y0 else lm.y_m - shift)
    landmarks = [{**dataclasses.asdict(lm), "x_m": moved[lm.name][0], "y_m": moved[lm.name][1]} for lm in config.landmarks]
    overrides: dict[str, Any] = {"landmarks": landmarks}
    for camera, sensor in config.sensors.items():
        if not isinstance(sensor, BearingCameraConfig):
            continue
        names = [lm.name for lm in config.landmarks]
        distractors = []
        for _ in sensor.distractors:
            name = names[int(rng.integers(len(names)))]
            lx, ly = moved[name]
            # the field lines the imitated landmark stands on: below, right, above, left of the field
            lines = [i for i, on in enumerate((ly == y0, lx == x1, ly == y1, lx == x0)) if on]
            side = lines[int(rng.integers(len(lines)))]
            out = float(rng.uniform(*DISTRACTOR_OUT_M))
            shift = float(rng.uniform(*DISTRACTOR_ALONG_M)) * (1.0 if rng.random() < 0.5 else -1.0)
            ax, ay = min(max(lx + shift, x0), x1), min(max(ly + shift, y0), y1)  # along its line, within the field's length
            x, y = ((ax, y0 - out), (x1 + out, ay), (ax, y1 + out), (x0 - out, ay))[side]
            distractors.append({"landmark": name, "x_m": x, "y_m": y, "radius_m": float(rng.uniform(*DISTRACTOR_RADIUS_M))})
        overrides.setdefault("sensors", {})[camera] = {"distractors": distractors}
    keeper = {
        name: {"keeper_posts": [list(moved[p.name]) for p in sorted(posts, key=lambda lm: lm.x_m) if p.y_m == y1]}
        for name, crowd in config.crowds.items()
        if getattr(crowd, "keeper_posts", None) is not None
    }
    if keeper:
        overrides["crowds"] = keeper
    return overrides


register_layout("robocup_crowded", soccer_field_layout)


# ---------------------------------------------------------------------------------------- corridor

#: a door recess: its width along the corridor and its depth into the wall, m (the paper's corridor: 0.9 x 0.25)
RECESS_WIDTH_M = 0.9
RECESS_DEPTH_M = 0.25
#: an alcove's length along the corridor, m (its back is the field's edge; the paper's: 1.6 and 2 m)
ALCOVE_LENGTH_M = (1.6, 2.4)
#: door recesses and alcoves on each side (the paper's: 3 and 1 on the left, 2 and 2 on the right)
RECESSES_PER_SIDE = (2, 3)
ALCOVES_PER_SIDE = (1, 2)
#: the least wall between two openings, and between an opening and the field's ends, m
OPENING_GAP_M = 0.5
#: how far each target between the first and the last moves along the corridor, m
TARGET_SHIFT_M = 1.0
#: a sign's distance along the corridor from the target it stands beside, m (the paper's: 0.6 and 0.4)
SIGN_FROM_TARGET_M = (0.3, 0.8)
#: the ceiling's light panel and sprinkler pitch, m (the paper's building: 2.4 and 3.6)
LIGHT_PITCH_M = (1.8, 3.0)
SPRINKLER_PITCH_M = (3.0, 4.2)

_OPENING_TRIES = 1000


def _corridor_parts(config: WorldConfig) -> tuple[Any, str, Any]:
    """The world's corridor crowd, its ceiling's name and its ceiling, or a ConfigError naming what is missing."""
    from envs.crowds.corridor import CorridorConfig
    from envs.features.ceiling import CeilingConfig

    corridors = [c for c in config.crowds.values() if isinstance(c, CorridorConfig)]
    ceilings = [(n, f) for n, f in config.features.items() if isinstance(f, CeilingConfig)]
    if len(corridors) != 1 or len(ceilings) != 1 or len(ceilings[0][1].targets) < 2:
        raise ConfigError(
            f"world {config.name!r}: the corridor layout needs one corridor crowd (its walls' centre and width) "
            f"and one ceiling with at least two targets"
        )
    return corridors[0], *ceilings[0]


def _openings(rng: np.random.Generator, y0: float, y1: float, lengths: list[float], where: str) -> list[tuple[float, float]]:
    """Non-overlapping ``[start, end]`` spans of ``lengths`` (in their order) in ``[y0, y1]``, ``OPENING_GAP_M`` apart
    and from the ends."""
    for _ in range(_OPENING_TRIES):
        spans: list[tuple[float, float]] = []
        for length in lengths:
            start = float(rng.uniform(y0 + OPENING_GAP_M, y1 - OPENING_GAP_M - length))
            if all(start + length + OPENING_GAP_M <= a or b + OPENING_GAP_M <= start for a, b in spans):
                spans.append((start, start + length))
        if len(spans) == len(lengths):
            return spans
    raise ConfigError(f"{where}: {len(lengths)} openings of {sum(lengths):.1f} m in all do not fit in {y1 - y0:g} m")


def corridor_layout(config: WorldConfig, rng: np.random.Generator) -> dict[str, Any]:
    """A corridor's layout: its door recesses and alcoves, its inner targets, signs and ceiling pitch (module docstring)."""
    corridor, name, ceiling = _corridor_parts(config)
    x0, y0, x1, y1 = config.field_m
    walls: list[list[float]] = []
    for side in (-1.0, 1.0):
        wall_x = corridor.centre_x_m + side * corridor.half_width_m
        edge_x = x1 if side > 0 else x0
        kinds = ["recess"] * int(rng.integers(RECESSES_PER_SIDE[0], RECESSES_PER_SIDE[1] + 1))
        kinds += ["alcove"] * int(rng.integers(ALCOVES_PER_SIDE[0], ALCOVES_PER_SIDE[1] + 1))
        kinds = [kinds[i] for i in rng.permutation(len(kinds))]
        lengths = [RECESS_WIDTH_M if k == "recess" else float(rng.uniform(*ALCOVE_LENGTH_M)) for k in kinds]
        spans = _openings(rng, y0, y1, lengths, f"world {config.name!r}, the {'right' if side > 0 else 'left'} wall")
        cursor = y0
        for (start, end), kind in sorted(zip(spans, kinds)):
            walls.append([wall_x, cursor, wall_x, start])
            if kind == "recess":
                back = wall_x + side * RECESS_DEPTH_M
                walls += [[wall_x, start, back, start], [back, start, back, end], [back, end, wall_x, end]]
            else:
                walls += [[wall_x, start, edge_x, start], [edge_x, end, wall_x, end]]
            cursor = end
        walls.append([wall_x, cursor, wall_x, y1])
    targets = [dataclasses.asdict(t) for t in ceiling.targets]
    for t in targets[1:-1]:
        t["y_m"] = float(t["y_m"] + rng.uniform(-TARGET_SHIFT_M, TARGET_SHIFT_M))
    inner = targets[1:-1] or targets
    signs = []
    for sign in ceiling.signs:
        beside = inner[int(rng.integers(len(inner)))]
        along = float(rng.uniform(*SIGN_FROM_TARGET_M)) * (1.0 if rng.random() < 0.5 else -1.0)
        across = abs(sign.x_m) * (1.0 if rng.random() < 0.5 else -1.0)
        signs.append({**dataclasses.asdict(sign), "x_m": across, "y_m": beside["y_m"] + along})
    light_pitch = float(rng.uniform(*LIGHT_PITCH_M))
    sprinkler_pitch = float(rng.uniform(*SPRINKLER_PITCH_M))
    return {
        "walls": walls,
        "features": {
            name: {
                "targets": targets,
                "signs": signs,
                "light_pitch_m": light_pitch,
                "light_first_y_m": float(rng.uniform(0.0, light_pitch)),
                "sprinkler_pitch_m": sprinkler_pitch,
                "sprinkler_first_y_m": float(rng.uniform(0.0, sprinkler_pitch)),
                "tile_origin_m": [float(rng.uniform(0.0, ceiling.tile_m)), float(rng.uniform(0.0, ceiling.tile_m))],
            }
        },
    }


register_layout("ceiling_corridor", corridor_layout)


# -------------------------------------------------------------------------------------------- room

#: the middle of the room kept clear for the robot: its start region grown by this much, m (the task's square runs there)
ROOM_CLEAR_M = 0.8
#: a queue's line: its distance from its side wall, m (the paper's room: 0.5 on both sides)
QUEUE_FROM_WALL_M = (0.4, 0.9)
#: the queues' heads: their distance from the top wall, m (0.5)
QUEUE_HEAD_FROM_WALL_M = (0.4, 1.1)
#: the distance between two people in a queue, m (0.4); less where the longest queue would reach the bottom wall
QUEUE_SPACING_M = (0.35, 0.5)
#: the door's leaf: its length, m (0.8), and its angle to the wall it is hinged on, rad (90 deg)
DOOR_LEAF_M = (0.7, 0.9)
DOOR_ANGLE_RAD = (np.pi / 3, 2 * np.pi / 3)
#: the legs of the bevelled corner, m (0.4)
BEVEL_M = (0.3, 0.6)
#: the least gap between two pieces (furniture, door, bevel), and between a piece and the people's places and paths, m
ROOM_GAP_M = 0.2
#: the occupancy grid the placement is checked on, m a cell
_ROOM_GRID_M = 0.05
_ROOM_TRIES = 200


class _RoomGrid:
    """Cell centres of a room's floor, and what is taken: the places of the room's pieces checked against each other."""

    def __init__(self, field_m: tuple[float, float, float, float]) -> None:
        x0, y0, x1, y1 = field_m
        xs = np.arange(x0 + _ROOM_GRID_M / 2, x1, _ROOM_GRID_M)
        ys = np.arange(y0 + _ROOM_GRID_M / 2, y1, _ROOM_GRID_M)
        self.x, self.y = np.meshgrid(xs, ys, indexing="ij")
        self.field = field_m
        self.taken = np.zeros(self.x.shape, dtype=bool)

    def box(self, cx: float, cy: float, length: float, depth: float, angle: float, grow: float = 0.0) -> np.ndarray:
        c, s = np.cos(angle), np.sin(angle)
        u = (self.x - cx) * c + (self.y - cy) * s
        v = -(self.x - cx) * s + (self.y - cy) * c
        return (np.abs(u) <= length / 2 + grow) & (np.abs(v) <= depth / 2 + grow)

    def capsule(self, a: tuple[float, float], b: tuple[float, float], radius: float) -> np.ndarray:
        ex, ey = b[0] - a[0], b[1] - a[1]
        length2 = ex * ex + ey * ey
        t = np.zeros(self.x.shape) if length2 == 0 else np.clip(((self.x - a[0]) * ex + (self.y - a[1]) * ey) / length2, 0, 1)
        return np.hypot(self.x - (a[0] + t * ex), self.y - (a[1] + t * ey)) <= radius

    def polygon(self, corners: list[tuple[float, float]], grow: float) -> np.ndarray:
        """A convex polygon (its corners in either turning order) grown by ``grow``."""
        left = np.ones(self.x.shape, dtype=bool)
        right = np.ones(self.x.shape, dtype=bool)
        near = np.zeros(self.x.shape, dtype=bool)
        for a, b in zip(corners, corners[1:] + corners[:1]):
            cross = (b[0] - a[0]) * (self.y - a[1]) - (b[1] - a[1]) * (self.x - a[0])
            left &= cross >= 0
            right &= cross <= 0
            near |= self.capsule(a, b, grow)
        return left | right | near

    def place(self, mask: np.ndarray, grow_mask: np.ndarray | None = None) -> bool:
        """Take ``grow_mask`` (default ``mask``) if ``mask`` is free; whether it was."""
        if (mask & self.taken).any():
            return False
        self.taken |= mask if grow_mask is None else grow_mask
        return True

    def inside(self, corners: np.ndarray) -> bool:
        x0, y0, x1, y1 = self.field
        return bool(np.all(corners[:, 0] >= x0) and np.all(corners[:, 0] <= x1) and np.all(corners[:, 1] >= y0)
                    and np.all(corners[:, 1] <= y1))  # fmt: skip


def _room_parts(config: WorldConfig) -> tuple[str, Any]:
    """The world's queues crowd (its name and config), or a ConfigError naming what is missing."""
    from envs.crowds.queues import QueuesConfig

    queues = [(n, c) for n, c in config.crowds.items() if isinstance(c, QueuesConfig)]
    if len(queues) != 1 or config.robot.start_region_m is None or len(config.walls) != 2:
        raise ConfigError(
            f"world {config.name!r}: the room layout needs one queues crowd, a robot start region and two walls "
            f"besides the room's own (a bevelled corner, then a door's leaf)"
        )
    return queues[0]


#: the room's walls in the order a layout draws them (bottom, right, top, left), and the direction into the room
#: turned from each one's own run along it
_WALL_TURN_RAD = (0.0, np.pi / 2, np.pi, -np.pi / 2)


def _wall_point(field_m: tuple[float, float, float, float], wall: int, along: float, inset: float = 0.0) -> tuple[float, float]:
    """The point ``along`` metres along wall ``wall`` (counter-clockwise round the room from its start) and ``inset``
    metres into the room."""
    x0, y0, x1, y1 = field_m
    return [(x0 + along, y0 + inset), (x1 - inset, y0 + along), (x1 - along, y1 - inset), (x0 + inset, y1 - along)][wall]


def _room_queues(config: WorldConfig, queues: Any, rng: np.random.Generator, grid: _RoomGrid) -> dict[str, float]:
    """The queues' lines, heads and spacing; marks their places and the heads' walks (at the largest crowd) taken."""
    x0, y0, x1, y1 = config.field_m
    left = x0 + float(rng.uniform(*QUEUE_FROM_WALL_M))
    right = x1 - float(rng.uniform(*QUEUE_FROM_WALL_M))
    head = y1 - float(rng.uniform(*QUEUE_HEAD_FROM_WALL_M))
    slots = -(-queues.max_count // 2)  # a queue's places at the largest crowd (a walking head takes the last)
    lowest = y0 + queues.radius_m + ROOM_GAP_M
    most = (head - lowest) / max(slots - 1, 1)
    if most < QUEUE_SPACING_M[0]:
        raise ConfigError(f"world {config.name!r}: {slots} people a queue do not fit between y = {head:.2f} and the bottom wall")
    spacing = float(rng.uniform(QUEUE_SPACING_M[0], min(QUEUE_SPACING_M[1], most)))
    tail = head - (slots - 1) * spacing
    grow = queues.radius_m + ROOM_GAP_M
    for x, other in ((left, right), (right, left)):
        grid.taken |= grid.capsule((x, head), (x, tail), grow)  # the queue itself
        grid.taken |= grid.polygon([(x, head), (other, head), (other, tail)], grow)  # a head's walk to the other queue
    return {"left_x_m": left, "right_x_m": right, "head_y_m": head, "spacing_m": spacing}


def room_layout(config: WorldConfig, rng: np.random.Generator) -> dict[str, Any]:
    """A room's layout: its queues, its door, its bevelled corner and where its furniture stands (module docstring)."""
    name, queues = _room_parts(config)
    x0, y0, x1, y1 = config.field_m
    corners = {(x0, y0): (1, 1), (x1, y0): (-1, 1), (x1, y1): (-1, -1), (x0, y1): (1, -1)}
    for _ in range(_ROOM_TRIES):
        grid = _RoomGrid(config.field_m)
        sx0, sy0, sx1, sy1 = config.robot.start_region_m  # type: ignore[misc]
        g = ROOM_CLEAR_M
        grid.taken |= grid.box((sx0 + sx1) / 2, (sy0 + sy1) / 2, sx1 - sx0 + 2 * g, sy1 - sy0 + 2 * g, 0.0)
        crowd = _room_queues(config, queues, rng, grid)
        # the bevel: a corner cut by a segment of legs a, b
        (cx, cy), (dx, dy) = list(corners.items())[int(rng.integers(4))]
        a, b = float(rng.uniform(*BEVEL_M)), float(rng.uniform(*BEVEL_M))
        bevel = [cx + dx * a, cy, cx, cy + dy * b]
        cut = [(cx, cy), (cx + dx * a, cy), (cx, cy + dy * b)]
        if not grid.place(grid.polygon(cut, ROOM_GAP_M)):
            continue
        # the door: hinged on a wall, 0.5 m or more from the corners, its leaf standing into the room
        wall = int(rng.integers(4))  # bottom, right, top, left
        leaf = float(rng.uniform(*DOOR_LEAF_M))
        angle = float(rng.uniform(*DOOR_ANGLE_RAD))
        along = float(rng.uniform(0.5, (x1 - x0 if wall % 2 == 0 else y1 - y0) - 0.5))
        hinge, inward = _wall_point(config.field_m, wall, along), _WALL_TURN_RAD[wall]
        tip = (hinge[0] + leaf * np.cos(inward + angle), hinge[1] + leaf * np.sin(inward + angle))
        if not grid.place(grid.capsule(hinge, tip, ROOM_GAP_M)):
            continue
        furniture = _room_furniture(config, rng, grid)
        if furniture is not None:
            return {"walls": [bevel, [*hinge, *tip]], "furniture": furniture, "crowds": {name: crowd}}
    raise ConfigError(f"world {config.name!r}: no room layout found in {_ROOM_TRIES} tries (the pieces do not fit)")


def _room_furniture(config: WorldConfig, rng: np.random.Generator, grid: _RoomGrid) -> list[dict[str, Any]] | None:
    """Each piece placed: a box with its back to a random wall, a table anywhere free; None if one finds no place."""
    x0, y0, x1, y1 = config.field_m
    placed = []
    for piece in config.furniture:
        for _ in range(_ROOM_TRIES):
            length, depth = piece.size_m
            if piece.kind == "box":
                wall = int(rng.integers(4))  # bottom, right, top, left: the piece's back against it
                angle = _WALL_TURN_RAD[wall]
                span = (x1 - x0 if wall % 2 == 0 else y1 - y0) - length
                cx, cy = _wall_point(config.field_m, wall, float(rng.uniform(0.0, span)) + length / 2, depth / 2)
            else:
                angle = float(rng.choice([0.0, np.pi / 2]))
                cx, cy = float(rng.uniform(x0, x1)), float(rng.uniform(y0, y1))
            offset = float(np.hypot(*piece.map_offset_m))  # the map's copy: as far off as the world's, any way
            turn = float(rng.uniform(-np.pi, np.pi))
            moved = dataclasses.replace(piece, x_m=cx, y_m=cy, angle_rad=angle,
                                        map_offset_m=(offset * np.cos(turn), offset * np.sin(turn)))  # fmt: skip
            if not (grid.inside(moved.footprint()) and grid.inside(moved.footprint(in_map=True))):
                continue
            if grid.place(grid.box(cx, cy, length, depth, angle), grid.box(cx, cy, length, depth, angle, ROOM_GAP_M)):
                placed.append(dataclasses.asdict(moved))
                break
        else:
            return None
    return placed


register_layout("crowded_room", room_layout)


# ------------------------------------------------------------------------------------------ campus

#: the paper's buildings: 8-22 m tall, m
BUILDING_HEIGHT_M = (8.0, 22.0)
#: each side of a building's footprint moved in by up to this much, m (and by at most BUILDING_INSET_SHARE of its depth)
BUILDING_INSET_M = 3.0
BUILDING_INSET_SHARE = 0.2
#: the façades' horizontal sizes (panels, pilasters, window pitch and width) times this factor
FACADE_SCALE = (0.8, 1.25)
#: each lamp, utility pole and tree moved up to this much along the path it lines (the nearest walkway or lane), m
ALONG_PATH_M = 4.0
#: the least gap between a moved pole or tree and a walkway's or lane's edge, a building, a parked car or the fence, m
CAMPUS_GAP_M = 0.3
#: half a road lane's width, m (3.5 m lanes)
LANE_HALF_WIDTH_M = 1.75
_CAMPUS_TRIES = 20


def _campus_parts(config: WorldConfig) -> tuple[Any, tuple[str, Any], tuple[str, Any] | None, tuple[str, Any] | None]:
    """The world's campus crowd and its buildings', poles' and trees' features (name, config), or a ConfigError."""
    from envs.crowds.campus.config import CampusConfig
    from envs.features.scenery import BuildingsConfig, PolesConfig, TreesConfig

    def one(kind: type) -> list[tuple[str, Any]]:
        return [(n, f) for n, f in config.features.items() if isinstance(f, kind)]

    campus = [c for c in config.crowds.values() if isinstance(c, CampusConfig)]
    buildings, poles, trees = one(BuildingsConfig), one(PolesConfig), one(TreesConfig)
    if len(campus) != 1 or len(buildings) != 1 or len(poles) > 1 or len(trees) > 1:
        raise ConfigError(
            f"world {config.name!r}: the campus layout needs one campus crowd (its walkways and lanes), one buildings "
            f"feature and at most one poles and one trees feature"
        )
    return campus[0], buildings[0], poles[0] if poles else None, trees[0] if trees else None


def _segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    e = b - a
    t = float(np.clip(np.dot(p - a, e) / np.dot(e, e), 0.0, 1.0))
    return float(np.hypot(*(p - (a + t * e))))


class _CampusGround:
    """Where a lamp, pole or tree may stand on a campus: off its walkways, lanes, buildings and parked cars."""

    def __init__(self, config: WorldConfig, campus: Any, footprints: list[np.ndarray]) -> None:
        from envs.bodies import CarConfig

        car = CarConfig()
        self.paths = [(np.asarray(w.points_m, dtype=np.float64), 0.5 * w.width_m) for w in campus.walkways]
        self.paths += [(np.asarray(lane.points_m, dtype=np.float64), LANE_HALF_WIDTH_M) for lane in campus.lanes]
        self.parked = [np.asarray(p[:2], dtype=np.float64) for p in campus.parked]
        self.car_radius = 0.5 * float(np.hypot(car.length_m, car.width_m))
        self.footprints = footprints
        self.field = config.field_m

    def direction(self, p: np.ndarray) -> np.ndarray:
        """The unit direction of the path segment nearest ``p``."""
        best, out = np.inf, np.array([1.0, 0.0])
        for points, _ in self.paths:
            for a, b in zip(points[:-1], points[1:]):
                d = _segment_distance(p, a, b)
                if d < best:
                    best, out = d, (b - a) / np.hypot(*(b - a))
        return out

    def free(self, p: np.ndarray, radius: float) -> bool:
        x0, y0, x1, y1 = self.field
        r = radius + CAMPUS_GAP_M
        if not (x0 + r <= p[0] <= x1 - r and y0 + r <= p[1] <= y1 - r):
            return False
        for points, half in self.paths:
            if any(_segment_distance(p, a, b) < half + r for a, b in zip(points[:-1], points[1:])):
                return False
        if any(np.hypot(*(p - c)) < self.car_radius + r for c in self.parked):
            return False
        for corners in self.footprints:
            edges = np.roll(corners, -1, axis=0) - corners
            cross = edges[:, 0] * (p[1] - corners[:, 1]) - edges[:, 1] * (p[0] - corners[:, 0])
            if np.all(cross >= 0) or min(_segment_distance(p, a, b) for a, b in zip(corners, np.roll(corners, -1, 0))) < r:
                return False
        return True

    def moved(self, item: Any, radius: float, rng: np.random.Generator) -> dict[str, Any]:
        """``item`` (a pole or tree) moved along its path to a free place, or where it stood if none is found."""
        at = np.array([item.x_m, item.y_m], dtype=np.float64)
        along = self.direction(at)
        for _ in range(_CAMPUS_TRIES):
            p = at + float(rng.uniform(-ALONG_PATH_M, ALONG_PATH_M)) * along
            if self.free(p, radius):
                return {**dataclasses.asdict(item), "x_m": float(p[0]), "y_m": float(p[1])}
        return dataclasses.asdict(item)


def _inset_footprint(corners: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """``corners`` mapped from their bounding box onto that box with each side moved in (a convex shape stays convex)."""
    lo, hi = corners.min(axis=0), corners.max(axis=0)
    size = hi - lo
    cap = np.minimum(BUILDING_INSET_M, BUILDING_INSET_SHARE * size)
    new_lo = lo + rng.uniform(0.0, 1.0, 2) * cap
    new_hi = hi - rng.uniform(0.0, 1.0, 2) * cap
    return new_lo + (corners - lo) * (new_hi - new_lo) / size


def _scaled_facade(facade: Any, scale: float) -> dict[str, Any]:
    out = dataclasses.asdict(facade)
    for key in ("panel_m", "column_pitch_m", "column_width_m", "window_pitch_m"):
        out[key] = float(out[key] * scale)
    out["window_size_m"] = [float(out["window_size_m"][0] * scale), float(out["window_size_m"][1])]
    return out


def campus_layout(config: WorldConfig, rng: np.random.Generator) -> dict[str, Any]:
    """A campus's layout: its buildings' footprints, heights and façades, where its lamps, poles and trees stand."""
    campus, (b_name, buildings), poles, trees = _campus_parts(config)
    facades = [b.facade or buildings.facade for b in buildings.items]  # shuffled among the buildings
    order = rng.permutation(len(facades))
    items = []
    for building, k in zip(buildings.items, order):
        corners = _inset_footprint(building.corners, rng)
        items.append({
            **dataclasses.asdict(building),
            "footprint_m": [[float(x), float(y)] for x, y in corners],
            "height_m": float(rng.uniform(*BUILDING_HEIGHT_M)),
            "facade": _scaled_facade(facades[k], float(rng.uniform(*FACADE_SCALE))),
        })  # fmt: skip
    features: dict[str, Any] = {b_name: {"items": items}}
    ground = _CampusGround(config, campus, [np.asarray(b["footprint_m"]) for b in items])
    if poles is not None:
        features[poles[0]] = {"items": [ground.moved(p, p.radius_m, rng) for p in poles[1].items]}
    if trees is not None:
        features[trees[0]] = {"items": [ground.moved(t, t.trunk_radius_m, rng) for t in trees[1].items]}
    return {"features": features}


register_layout("stereo_campus", campus_layout)
