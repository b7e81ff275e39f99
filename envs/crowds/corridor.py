"""People in a long corridor: pedestrians walking both ways and small groups standing by the walls.

The ceiling-target paper's corridor (``configs/worlds/ceiling_corridor.yaml``). The corridor runs
along y over the whole field, between straight walls at ``x = centre_x_m +- half_width_m`` from
which door recesses and alcoves open outward; the rest of the field behind those walls is
closed void, where nobody is ever placed.

Walkers (the first ``count`` members, the density that ``crowd_size`` sets) walk along the
corridor toward +y or -y at their own desired speed, keeping loosely to their right-hand side
(a lane centre offset from the centre line), with the social force of
:func:`envs.crowds.walkers.social_force_velocities` keeping them off each other, the standing
people, the walls and, more strongly, the robot; one with a standing person or the robot in its
lane ahead steps aside to pass. A walker that reaches the end it walks toward
steps out there and comes back in at the other end, walking the same way (see
:class:`CorridorConfig` for why). Standing people (the members after the walkers) stand in
small groups turned toward each other near the walls, in alcoves and door recesses where a
group fits and just in front of the wall elsewhere; they fidget around their spots and walk
back to them when pushed away. Everyone is a force-driven disc: they shove each other and the
robot, which odometry never sees.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numba
import numpy as np
from numpy.typing import NDArray

from core.raycast import cast_rays
from core.schema import ConfigError, check, check_ranges
from envs.crowds.base import Commands, Crowd, PeopleConfig, Taken, register_crowd
from envs.crowds.queues import PEOPLE_FILL
from envs.crowds.steering import SEEK_RELAXATION_S, seek
from envs.crowds.walkers import SPEED_CAP, social_force_velocities
from envs.state import Rows, WorldState

if TYPE_CHECKING:
    from envs.config import WorldConfig

STANDING_FILL = (150, 95, 165)  # standing people, to tell them from the walkers (PEOPLE_FILL)
_PLACE_GAP_M = 0.05  # free space left between people placed at a reset or a re-entry
_PLACE_TRIES = 1000  # random spots tried per group before giving up


class _NoRoom(RuntimeError):
    """A standing group found no free spot by the walls."""


_ENTRY_TRIES = 12  # spots across the corridor tried for a walker coming back in, this step
_GROUP_TURN_RAD = math.radians(20.0)  # a group's ring is turned at random by up to this much
_PASS_GAP_M = 0.1  # walkers stepping aside pass this far clear of the one in their way
_NO_CIRCLES = np.zeros((0, 2))
_NO_RADII = np.zeros(0)


@dataclass(frozen=True)
class CorridorConfig(PeopleConfig):
    """Walkers both ways along a corridor and groups standing by its walls.

    ``count`` is the number of walkers only: the crowd density, which ``crowd_size`` sets and
    a density sweep varies (up to ``max_count``). The standing people come on top of them:
    ``groups`` groups whose sizes are ``group_sizes`` taken in turn (``(3, 2)``: 3, 2, 3, 2, ...;
    bodies are made when the world is built, so the sizes are set, not drawn), the same at every
    density but 0. Density 0 is the empty corridor, nobody standing either (the paper's drive,
    and what ``crowd_size=0`` means in every world); ``groups: 0`` leaves the walkers alone.

    A walker that reaches the end it walks toward (``end_margin_m`` before the field's edge)
    re-enters at the other end walking the same way, rather than turning around: the number
    walking each way then stays exactly what was drawn at the reset, at every step, and people
    are spread over the whole length as in a corridor open at both ends. Turning around would
    let the two directions drift toward half and half whatever ``plus_y_share`` says, and bunch
    people at the ends while they turn. The person coming back in keeps its speed and lane
    and enters on its lane, or at a free spot across the corridor if someone stands there (it
    waits at the end while none is free).

    Attributes:
        count: walkers (the density); ``max_count``: the most ``count`` may be.
        radius_m, mass_kg: a person's footprint disc and weight.
        speed_mps: the standing people's top speed, walking back to their spots when pushed off.
        walk_speed_mps: ``(low, high)``: each walker's desired speed is drawn uniformly in it.
        plus_y_share: the share of the walkers walking toward +y (the others walk toward -y).
        lane_offset_m: ``(low, high)``: each walker keeps this far to the right of the centre
            line (drawn uniformly per walker), loosely: the social force moves it off its lane.
        lookahead_m: walkers head for a point on their lane this far ahead.
        detour_ahead_m: a standing person or the robot on a walker's lane less than this far
            ahead makes it step aside (toward the corridor's centre for people by a wall); 0: never.
        relaxation_s, repulsion_strength_mps2, repulsion_range_m: the social force (as walkers').
        robot_repulsion_gain: the robot repels walkers this many times as strongly as a person.
        centre_x_m, half_width_m: the centre line and the half width between the straight walls.
        end_margin_m: walkers leave this far before the field's ends and re-enter this far inside.
        groups, group_sizes: the standing groups and their sizes (cycled).
        group_spacing_m: centre distance of neighbours in a group (on a ring, facing its centre).
        wall_gap_m: standing people keep this far from the walls.
        clear_half_width_m: standing people leave the strip this wide either side of the centre
            line free (the robot's drive line); a group that does not fit in front of a wall
            there finds an alcove or a door recess.
        fidget_m: a standing person shifts to a random point this far from its spot at most ...
        fidget_period_s: ``(low, high)``: ... every this many seconds (drawn each time).
    """

    shape: str = "person"  # legs, a torso and a head (envs.bodies); the footprint disc collides

    count: int = 0
    max_count: int = 40
    radius_m: float = 0.2
    mass_kg: float = 70.0
    speed_mps: float = 0.5
    walk_speed_mps: tuple[float, float] = (1.0, 1.4)
    plus_y_share: float = 0.5
    lane_offset_m: tuple[float, float] = (0.45, 0.8)
    lookahead_m: float = 1.5
    detour_ahead_m: float = 3.0
    relaxation_s: float = 0.5
    repulsion_strength_mps2: float = 2.0
    repulsion_range_m: float = 0.3
    robot_repulsion_gain: float = 3.0
    centre_x_m: float = 0.0
    half_width_m: float = 1.0
    end_margin_m: float = 0.5
    groups: int = 3
    group_sizes: tuple[int, ...] = (3, 2)
    group_spacing_m: float = 0.55
    wall_gap_m: float = 0.05
    clear_half_width_m: float = 0.3
    fidget_m: float = 0.08
    fidget_period_s: tuple[float, float] = (1.0, 4.0)

    def __post_init__(self) -> None:
        super().__post_init__()
        lo, hi = self.walk_speed_mps
        check(0 < lo <= hi, f"corridor.walk_speed_mps must be (low, high) with 0 < low <= high, got {self.walk_speed_mps}")
        check(0 <= self.plus_y_share <= 1, f"corridor.plus_y_share must be in [0, 1], got {self.plus_y_share}")
        check(
            self.half_width_m > self.radius_m,
            f"corridor.half_width_m must be > radius_m ({self.radius_m}), got {self.half_width_m}",
        )
        lane = self.half_width_m - self.radius_m
        lo, hi = self.lane_offset_m
        check(
            0 <= lo <= hi <= lane,
            f"corridor.lane_offset_m must be (low, high) with 0 <= low <= high <= half_width_m - radius_m ({lane:g}), "
            f"got {self.lane_offset_m}",
        )
        check_ranges(
            self,
            "corridor",
            positive=("lookahead_m", "relaxation_s", "repulsion_range_m"),
            non_negative=(
                "detour_ahead_m",
                "repulsion_strength_mps2",
                "robot_repulsion_gain",
                "end_margin_m",
                "wall_gap_m",
                "fidget_m",
            ),
        )
        check(self.groups >= 0, f"corridor.groups must be >= 0, got {self.groups}")
        check(
            len(self.group_sizes) > 0 and all(1 <= n <= 6 for n in self.group_sizes),
            f"corridor.group_sizes must be one or more sizes in [1, 6], got {self.group_sizes}",
        )
        check(
            self.group_spacing_m >= 2 * self.radius_m,
            f"corridor.group_spacing_m must be >= 2 radius_m ({2 * self.radius_m:g}: people in a group do not overlap), "
            f"got {self.group_spacing_m}",
        )
        check(
            0 <= self.clear_half_width_m < self.half_width_m,
            f"corridor.clear_half_width_m must be in [0, half_width_m ({self.half_width_m})), got {self.clear_half_width_m}",
        )
        lo, hi = self.fidget_period_s
        check(0 < lo <= hi, f"corridor.fidget_period_s must be (low, high) with 0 < low <= high, got {self.fidget_period_s}")

    def top_speeds(self) -> tuple[tuple[str, float, float], ...]:
        """The walkers (the social force's cap times the top of ``walk_speed_mps``) and the standing people (``speed_mps``)."""
        return (
            ("walkers", SPEED_CAP * self.walk_speed_mps[1], self.radius_m),
            ("standing people", self.speed_mps, self.radius_m),
        )

    @property
    def sizes(self) -> tuple[int, ...]:
        """The size of each standing group: ``group_sizes`` cycled over ``groups``; none at ``count`` 0."""
        groups = self.groups if self.count > 0 else 0
        return tuple(self.group_sizes[g % len(self.group_sizes)] for g in range(groups))


def group_ring(size: int, spacing_m: float, turn_rad: float) -> NDArray[np.float64]:
    """``(size, 2)`` offsets ``(u, v)`` of a group's people from its centre, ``u`` toward the
    corridor's centre line and ``v`` along it: a ring with neighbours ``spacing_m`` apart, turned
    by ``turn_rad``. Two people stand side by side along the wall, three as a triangle with its
    point toward the corridor."""
    if size == 1:
        return np.zeros((1, 2))
    radius = spacing_m / (2.0 * math.sin(math.pi / size))
    phase = math.pi / size if size % 2 == 0 else 0.0
    phi = phase + turn_rad + 2.0 * math.pi * np.arange(size) / size
    return radius * np.stack([np.cos(phi), np.sin(phi)], axis=1)


def wall_clearance(points: NDArray[np.float64], seg_a: NDArray[np.float64], seg_b: NDArray[np.float64]) -> NDArray[np.float64]:
    """``(P,)`` distance from each point ``(P, 2)`` to the nearest wall segment."""
    d = seg_b - seg_a
    length2 = np.maximum(np.sum(d * d, axis=1), 1e-12)
    rel = points[:, None, :] - seg_a[None]
    t = np.clip(np.sum(rel * d[None], axis=2) / length2, 0.0, 1.0)
    return np.min(np.linalg.norm(rel - t[..., None] * d[None], axis=2), axis=1)


@numba.njit(cache=True)
def detour_lanes(
    pos: NDArray[np.float64],
    direction: NDArray[np.float64],
    lane_x: NDArray[np.float64],
    obstacles: NDArray[np.float64],
    obstacle_r: NDArray[np.float64],
    radius: float,
    ahead: float,
    x_low: float,
    x_high: float,
) -> NDArray[np.float64]:
    """``(N,)`` the x each walker heads for: its lane, or beside whoever stands in it ahead.

    An obstacle (a standing person, the robot) blocks walker ``i`` when it is less than
    ``ahead`` in front of it along its direction (or not yet passed) and nearer its lane than
    their radii and a gap; the walker then heads for the side of it nearer its lane, or the
    other side where that leaves the walkable band ``[x_low, x_high]``. Repeated for whoever
    blocks the new line (a group of several), a few times at most.
    """
    n = pos.shape[0]
    out = lane_x.copy()
    for i in range(n):
        gx = lane_x[i]
        for _ in range(4):
            best = math.inf
            bj = -1
            for j in range(obstacles.shape[0]):
                reach = obstacle_r[j] + radius + _PASS_GAP_M
                dy = (obstacles[j, 1] - pos[i, 1]) * direction[i]
                if -reach < dy < ahead and abs(obstacles[j, 0] - gx) < reach and dy < best:
                    best = dy
                    bj = j
            if bj < 0:
                break
            ox = obstacles[bj, 0]
            reach = obstacle_r[bj] + radius + _PASS_GAP_M
            side = 1.0 if gx >= ox else -1.0
            x = ox + side * reach
            if x < x_low or x > x_high:
                x = ox - side * reach
            x = min(max(x, x_low), x_high)
            if x == gx:
                break
            gx = x
        out[i] = gx
    return out


def refresh_fidgets(
    fidget: NDArray[np.float64],
    next_s: NDArray[np.float64],
    time_s: float,
    reach_m: float,
    period_s: tuple[float, float],
    rng: np.random.Generator,
) -> None:
    """Standing people whose time has come (``next_s <= time_s``) shift to a new point, uniform
    over the disc of radius ``reach_m`` around their spots (``fidget`` ``(standing, 2)``: the
    offsets), and draw when they shift next, ``period_s`` (low, high) later; in place. The
    corridor's and the campus's standing people."""
    due = time_s >= next_s
    if due.any():
        n = int(due.sum())
        angle = rng.uniform(-math.pi, math.pi, size=n)
        reach = reach_m * np.sqrt(rng.random(n))
        fidget[due] = reach[:, None] * np.stack([np.cos(angle), np.sin(angle)], axis=1)
        next_s[due] += rng.uniform(*period_s, size=n)


@register_crowd("corridor", CorridorConfig)
class CorridorCrowd(Crowd):
    """Walkers (members ``0 .. walkers - 1``) and standing people (the rest, group by group).

    Attributes:
        walkers: how many walk (``config.count``); ``standing``: how many stand.
        direction: ``(walkers,)`` +1 (toward +y) or -1, drawn at the reset.
        walk_speed_mps: ``(walkers,)`` desired speeds; ``lane_x_m``: ``(walkers,)`` lane centres.
        sizes: the standing groups' sizes (none at ``count`` 0); ``group_of``: ``(standing,)`` each
            standing person's group; ``group_centre``: ``(groups, 2)``.
        spot: ``(standing, 2)`` where each standing person stands (it fidgets around it).
    """

    fill = PEOPLE_FILL
    standing_fill = STANDING_FILL

    def __init__(self, name: str, config: CorridorConfig, world: WorldConfig) -> None:
        super().__init__(name, config, world)
        self.c = config
        self.dt_s = world.dt_s
        self.sizes = sizes = config.sizes
        self.walkers = int(config.count)
        self.standing = int(sum(sizes))
        self.size_members(self.walkers + self.standing)
        self.group_of = np.repeat(np.arange(len(sizes)), sizes).astype(np.int64)
        self.seg_a, self.seg_b = world.wall_segments()
        x0, y0, x1, y1 = world.field_m
        self.y_range = (y0, y1)
        cx, hw, r = config.centre_x_m, config.half_width_m, config.radius_m
        if not x0 <= cx - hw < cx + hw <= x1:
            raise ConfigError(
                f"crowd {name!r}: the corridor centre_x_m +- half_width_m ({cx - hw:g}..{cx + hw:g}) must lie inside the "
                f"field of world {world.name!r} (x {x0:g}..{x1:g})"
            )
        if y1 - y0 <= 2 * (config.end_margin_m + r):
            raise ConfigError(
                f"crowd {name!r}: end_margin_m {config.end_margin_m} leaves no corridor in world {world.name!r} "
                f"(the field is {y1 - y0:g} m long)"
            )
        self.walk_box = (
            cx - hw + r + 0.5 * _PLACE_GAP_M,
            y0 + config.end_margin_m,
            cx + hw - r - 0.5 * _PLACE_GAP_M,
            y1 - config.end_margin_m,
        )
        self._clear_state()
        self._gain_key: tuple[int, Any] = (-1, None)
        self._gain = np.ones(0)

    def _clear_state(self) -> None:
        w, s = self.walkers, self.standing
        self.direction = np.ones(w)
        self.walk_speed_mps = np.full(w, self.c.walk_speed_mps[0])
        self.lane_x_m = np.full(w, self.c.centre_x_m)
        self.spot = np.zeros((s, 2))
        self.group_centre = np.zeros((len(self.sizes), 2))
        self.fidget = np.zeros((s, 2))
        self.next_fidget_s = np.zeros(s)

    # ------------------------------------------------------------------ reset
    def reset(self, rng: np.random.Generator, taken: Taken) -> NDArray[np.float64]:
        super().reset(rng, taken)
        c = self.c
        self._clear_state()
        # standing groups first (they need the room by the walls), then the walkers around them
        self._place_groups(rng, taken)
        w = self.walkers
        walkers = self.free_positions(rng, w, c.radius_m, taken, box=self.walk_box)
        plus = int(math.floor(c.plus_y_share * w))
        plus += int(rng.random() < c.plus_y_share * w - plus)  # the share exactly, up to one walker
        self.direction = np.where(rng.permutation(w) < plus, 1.0, -1.0)
        self.walk_speed_mps = rng.uniform(*c.walk_speed_mps, size=w)
        self.lane_x_m = c.centre_x_m + self.direction * rng.uniform(*c.lane_offset_m, size=w)
        self.next_fidget_s = rng.uniform(*c.fidget_period_s, size=self.standing)
        self.draw_seers(rng)
        return np.concatenate([walkers, self.spot]).reshape(-1, 2)

    def _wall_depth(self, y: NDArray[np.float64], side: float) -> NDArray[np.float64]:
        """``(n,)`` distance from the centre line at each ``y`` to the first wall on ``side`` (+1: +x)."""
        angle = np.array([0.0 if side > 0 else math.pi])
        return np.array(
            [
                cast_rays(np.array([self.c.centre_x_m, yi]), angle, math.inf, self.seg_a, self.seg_b, _NO_CIRCLES, _NO_RADII)[0]
                for yi in y
            ]
        )

    def _place_groups(self, rng: np.random.Generator, taken: Taken) -> None:
        """Every standing group by a wall, in its listed order; where one finds no room (a smaller group took the
        only recess or alcove a larger one fits in), all of them again, the largest first, drawing on."""
        before = len(taken)
        orders = [list(range(len(self.sizes))), sorted(range(len(self.sizes)), key=lambda g: -self.sizes[g])]
        for attempt, order in enumerate(orders):
            try:
                for g in order:
                    self.group_centre[g], self.spot[self.group_of == g] = self._place_group(rng, g, self.sizes[g], taken)
                return
            except _NoRoom:
                del taken[before:]
                if attempt == len(orders) - 1:
                    raise

    def _place_group(
        self, rng: np.random.Generator, g: int, size: int, taken: Taken
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """A free spot by a wall for group ``g``: its centre ``(2,)`` and its people ``(size, 2)``."""
        c = self.c
        r = c.radius_m
        y0, y1 = self.y_range
        for _ in range(_PLACE_TRIES):
            ring = group_ring(size, c.group_spacing_m, rng.uniform(-_GROUP_TURN_RAD, _GROUP_TURN_RAD))
            reach = float(np.max(np.abs(ring[:, 1]))) + r
            side = 1.0 if rng.random() < 0.5 else -1.0
            gy = rng.uniform(y0 + c.end_margin_m + reach, y1 - c.end_margin_m - reach)
            y = gy + ring[:, 1]
            # as close to the wall as each person's stretch of it allows (a recess may be narrower than a group)
            depth = np.min([self._wall_depth(y + dy, side) for dy in (-r, 0.0, r)], axis=0)
            centre_u = float(np.min(depth - r - c.wall_gap_m + ring[:, 0]))
            off_centre = centre_u - ring[:, 0]  # each person's distance from the centre line
            people = np.stack([c.centre_x_m + side * off_centre, y], axis=1)
            if np.any(off_centre - r < c.clear_half_width_m):
                continue  # it would stand in the robot's way
            if np.any(wall_clearance(people, self.seg_a, self.seg_b) < r + 0.5 * c.wall_gap_m):
                continue  # a recess corner
            if any((px - x) ** 2 + (py - yy) ** 2 <= (rr + r + _PLACE_GAP_M) ** 2 for px, py in people for x, yy, rr in taken):
                continue
            taken += [(float(px), float(py), r) for px, py in people]
            return np.array([c.centre_x_m + side * centre_u, gy]), people
        raise _NoRoom(
            f"world {self.world_config.name!r}: no room by the walls for standing group {g} ({size} people) of crowd "
            f"{self.name!r}; ask for fewer or smaller groups (groups, group_sizes) or a narrower clear_half_width_m"
        )

    # ------------------------------------------------------------------ every step
    def _robot_gain(self, state: WorldState, others: Rows) -> NDArray[np.float64]:
        """``(M,)`` repulsion gain of each of ``others``: ``robot_repulsion_gain`` for the robot, 1 for people."""
        key = (state.body_count, others if isinstance(others, slice) else others.tobytes())
        if key != self._gain_key:
            rows = np.arange(state.body_count)[others]
            self._gain = np.where(rows == 0, self.c.robot_repulsion_gain, 1.0)
            self._gain_key = key
        return self._gain

    def commands(self, state: WorldState, others: Rows, rng: np.random.Generator) -> Commands:
        c = self.c
        w = self.walkers
        pos = state.positions[self.member_rows]
        vel = state.velocities[self.member_rows]
        out = np.zeros((self.count, 2))
        teleports: list[tuple[int, NDArray[np.float64]]] = []
        if w:
            # step aside for the standing people and the robot, then walk by social force
            obstacles = np.concatenate([state.positions[:1], pos[w:]])
            obstacle_r = np.concatenate([state.radii_m[:1], self.radii_m[w:]])
            xmin, _, xmax, _ = self.walk_box
            lane = detour_lanes(
                pos[:w], self.direction, self.lane_x_m, obstacles, obstacle_r, c.radius_m, c.detour_ahead_m, xmin, xmax
            )
            goals = np.stack([lane, pos[:w, 1] + self.direction * c.lookahead_m], axis=1)
            others_xy = state.positions[others]
            out[:w] = social_force_velocities(
                pos[:w],
                vel[:w],
                goals,
                others_xy,
                state.seg_a,
                state.seg_b,
                self.walk_speed_mps,
                c.relaxation_s,
                c.repulsion_strength_mps2,
                c.repulsion_range_m,
                self.dt_s,
                self._robot_gain(state, others),
            )
            self.react_to_robot(state, out, slice(0, w), SPEED_CAP * self.walk_speed_mps, self.dt_s)
            teleports = self._re_entries(state, others, pos[:w], vel[:w], out, rng)
        if self.standing:
            refresh_fidgets(self.fidget, self.next_fidget_s, state.time_s, c.fidget_m, c.fidget_period_s, rng)
            out[w:] = seek(pos[w:], self.spot + self.fidget, self.max_speed[w:], self.held[w:], self.radii_m[w:])
            self.react_to_robot(state, out, slice(w, self.count), self.max_speed[w:], SEEK_RELAXATION_S)
        out[self.held] = 0.0
        return Commands(out, None, tuple(teleports))

    def _re_entries(
        self,
        state: WorldState,
        others: Rows,
        pos: NDArray[np.float64],
        vel: NDArray[np.float64],
        out: NDArray[np.float64],
        rng: np.random.Generator,
    ) -> list[tuple[int, NDArray[np.float64]]]:
        """Walkers past the end they walk toward come back in at the other end (``out`` is
        changed: one waiting for a free spot stands still, one moved keeps its velocity, so that
        no force acts on it before it is moved)."""
        xmin, ymin, xmax, ymax = self.walk_box
        out_of = ((self.direction > 0) & (pos[:, 1] > ymax)) | ((self.direction < 0) & (pos[:, 1] < ymin))
        out_of &= ~self.held[: self.walkers]
        if not out_of.any():
            return []
        r = self.c.radius_m
        occupied_xy = [state.positions[others]]
        occupied_r = [state.radii_m[others]]
        moves: list[tuple[int, NDArray[np.float64]]] = []
        for i in np.flatnonzero(out_of):
            y = ymin if self.direction[i] > 0 else ymax
            xs = np.concatenate([[self.lane_x_m[i]], rng.uniform(xmin, xmax, size=_ENTRY_TRIES - 1)])
            xy_all, r_all = np.concatenate(occupied_xy), np.concatenate(occupied_r)
            for x in xs:
                spot = np.array([x, y])
                if np.all(np.sum((xy_all - spot) ** 2, axis=1) > (r_all + r + _PLACE_GAP_M) ** 2):
                    break
            else:
                out[i] = 0.0  # the way in is full: wait at the end
                continue
            moves.append((int(i), spot))
            out[i] = vel[i]
            occupied_xy.append(spot[None])
            occupied_r.append(np.array([r]))
        return moves

    # ------------------------------------------------------------------ drawing
    def facing_rad(self, state: WorldState) -> NDArray[np.float64]:
        """``(members,)`` where each person faces: a walker where it walks (its way along the
        corridor when nearly still), a standing person the centre of its group."""
        pos = state.positions[self.member_rows]
        vel = state.velocities[self.member_rows]
        w = self.walkers
        out = np.empty(self.count)
        moving = np.hypot(vel[:w, 0], vel[:w, 1]) > 0.1
        out[:w] = np.where(moving, np.arctan2(vel[:w, 1], vel[:w, 0]), self.direction * math.pi / 2)
        to_centre = self.group_centre[self.group_of] - pos[w:]
        out[w:] = np.arctan2(to_centre[:, 1], to_centre[:, 0])
        return out

    def draw(self, canvas: Any, state: WorldState) -> None:
        """Walkers and standing people as discs of two shades, each with a tick where it faces."""
        facing = self.facing_rad(state)
        radii = state.radii_m[self.member_rows]
        for i, ((x, y), r, a) in enumerate(zip(state.positions[self.member_rows], radii, facing)):
            canvas.circle(x, y, r, self.fill if i < self.walkers else self.standing_fill, 0)
            canvas.circle(x, y, r, self.outline, 1)
            canvas.line((x, y), (x + r * math.cos(a), y + r * math.sin(a)), self.outline, 1)
