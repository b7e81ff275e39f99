"""The campus crowd itself: its members, where they start, and what each wants every step.

:class:`CampusCrowd` (registered as ``campus``) builds the walkway network and the lanes from
its :class:`~envs.crowds.campus.config.CampusConfig`, places walkers, groups and cars at a
reset, and each step asks the kernels of :mod:`.walking` and :mod:`.traffic` for the walkers'
and the cars' velocities (the behaviour is described in :mod:`envs.crowds.campus`).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from core.schema import ConfigError
from envs.crowds.base import BodySpec, Commands, Crowd, Taken, register_crowd
from envs.crowds.campus.config import EDGE_GAP_M, CampusConfig, LaneConfig, WalkwayConfig
from envs.crowds.campus.polylines import Polylines
from envs.crowds.campus.traffic import (
    BOX,
    CAR_FILL,
    CAR_LEAVE_M,
    CAR_SIDE_GAP_M,
    DISC,
    PARKED_FILL,
    box_disc_gap,
    boxes_overlap,
    drive_velocities,
)
from envs.crowds.campus.walking import walk_velocities
from envs.crowds.corridor import STANDING_FILL, group_ring, refresh_fidgets
from envs.crowds.queues import PEOPLE_FILL
from envs.crowds.steering import SEEK_RELAXATION_S, give_way, seek
from envs.crowds.walkers import SPEED_CAP
from envs.state import Rows, WorldState

if TYPE_CHECKING:
    from envs.config import WorldConfig

_PLACE_GAP_M = 0.05  # free space left between bodies placed at a reset
_PLACE_TRIES = 1000  # random spots tried per walker or group before giving up
_PARKED_RETURN_MPS = 0.2  # a pushed parked car is drawn back to its spot at most this fast


@register_crowd("campus", CampusConfig)
class CampusCrowd(Crowd):
    """Walkers, standing people, moving and parked cars (in that body order; :mod:`envs.crowds.campus`).

    Attributes:
        walkers, standing, cars, parked_count: how many of each; ``sizes``: the groups' sizes.
        way, direction, keep, desired_mps: ``(walkers,)`` each walker's walkway, its direction
            along it (+1: in point order), its share of the free half width kept right, its speed.
        spot: ``(standing, 2)`` where each standing person stands; ``group_of``, ``group_centre``.
        lane: ``(cars,)`` each moving car's lane.
        walkways, lanes: the packed polylines (:class:`Polylines`).
        doors: ``(D, 4)`` each door's middle, outward heading and half width.
    """

    fill = PEOPLE_FILL
    standing_fill = STANDING_FILL

    def __init__(self, name: str, config: CampusConfig, world: WorldConfig) -> None:
        super().__init__(name, config, world)
        self.c = config
        self.dt_s = world.dt_s
        self.walkers, self.sizes, self.cars = config.split
        self.standing = int(sum(self.sizes))
        self.parked_count = len(config.parked) if config.count > 0 else 0  # none in the empty campus
        self.first_car = self.walkers + self.standing
        self.first_parked = self.first_car + self.cars
        self.size_members(self.first_parked + self.parked_count)
        self.radii_m[self.first_car :] = config.car.bounding_radius_m
        self.member_mass_kg[self.first_car :] = config.car_mass_kg
        self.group_of = np.repeat(np.arange(len(self.sizes)), self.sizes).astype(np.int64)
        self.car_half = np.array([0.5 * config.car.length_m, 0.5 * config.car.width_m])
        self._car_halves = np.tile(self.car_half, (self.count - self.first_car, 1))  # per car, for the walkers' kernel
        self._check_in_field(name, world)
        self._build_network(name, config.join_m)
        self.lanes = Polylines([np.asarray(lane.points_m, dtype=np.float64) for lane in config.lanes])
        self.doors = self._doors(world)
        if self.walkers and not config.walkways:
            raise ConfigError(f"crowd {name!r}: {self.walkers} walkers need walkways (campus.walkways is empty)")
        if self.cars and not config.lanes:
            raise ConfigError(f"crowd {name!r}: {self.cars} cars need lanes (campus.lanes is empty)")
        if self.cars:
            self._lane_shares()  # refuses a crowd whose cars cannot fit on their lanes
        if self.sizes and not (self.doors.shape[0] or config.walkways):
            raise ConfigError(f"crowd {name!r}: standing groups need buildings with doors or walkways to stand by")
        self._check_parked(name, np.asarray(config.parked, dtype=np.float64).reshape(-1, 3))
        self.parked_spots = np.asarray(config.parked[: self.parked_count], dtype=np.float64).reshape(-1, 3)
        segments = world.static_segments()
        floor = segments[:, 4] <= 0.0  # what stands on the floor: walls, buildings, poles, trunks
        self._seg = np.ascontiguousarray(segments[floor, :4])
        self._solids = self._solid_edges(world)
        self._clear_state()
        self._gain_key: tuple[int, Any] = (-1, None)
        self._gain = np.ones(0)
        self._kind = np.zeros(0, dtype=np.int64)
        self._start_headings = np.zeros(self.count)

    # ------------------------------------------------------------------ construction
    def _check_in_field(self, name: str, world: WorldConfig) -> None:
        xmin, ymin, xmax, ymax = world.field_m
        lines: list[tuple[str, WalkwayConfig | LaneConfig]] = [(f"walkway {k}", w) for k, w in enumerate(self.c.walkways)]
        lines += [(f"lane {k}", lane) for k, lane in enumerate(self.c.lanes)]
        for label, item in lines:
            pts = np.asarray(item.points_m, dtype=np.float64)
            bad = np.flatnonzero((pts[:, 0] < xmin) | (pts[:, 0] > xmax) | (pts[:, 1] < ymin) | (pts[:, 1] > ymax))
            if bad.size:
                raise ConfigError(
                    f"crowd {name!r}: {label} {item.name!r} point {pts[bad[0]].tolist()} is outside the field of "
                    f"world {world.name!r} (x {xmin:g}..{xmax:g}, y {ymin:g}..{ymax:g})"
                )

    def _check_parked(self, name: str, spots: NDArray[np.float64]) -> None:
        """Every parked spot (at any count) puts its car inside the field, clear of the others."""
        xmin, ymin, xmax, ymax = self.world_config.arena_m
        boxes = [self.c.car.footprint(*spot) for spot in spots]
        for spot, box in zip(spots, boxes):
            if not np.all((box >= (xmin, ymin)) & (box <= (xmax, ymax))):
                raise ConfigError(
                    f"crowd {name!r}: parked spot {tuple(float(v) for v in spot)} puts the car (corners "
                    f"{np.round(box, 2).tolist()}) outside the field of world {self.world_config.name!r} "
                    f"(x {xmin:g}..{xmax:g}, y {ymin:g}..{ymax:g})"
                )
        for a in range(len(boxes)):
            for b in range(a):
                if boxes_overlap(boxes[a], boxes[b], 0.0):
                    raise ConfigError(
                        f"crowd {name!r}: parked spots {tuple(spots[b].tolist())} and "
                        f"{tuple(spots[a].tolist())} overlap (a car is {self.c.car.length_m} x {self.c.car.width_m} m)"
                    )

    def _build_network(self, name: str, join_m: float) -> None:
        """The walkways packed, their ends' nodes (ends within ``join_m`` are one) and each node's ends."""
        c = self.c
        self.walkways = Polylines([np.asarray(w.points_m, dtype=np.float64) for w in c.walkways])
        self.half_width = np.array([0.5 * w.width_m for w in c.walkways], dtype=np.float64)
        count = len(c.walkways)
        ends = np.array([self.walkways.line(k)[e] for k in range(count) for e in (0, -1)]).reshape(-1, 2)
        parent = list(range(ends.shape[0]))

        def root(i: int) -> int:
            while parent[i] != i:
                parent[i] = parent[parent[i]]
                i = parent[i]
            return i

        for a in range(ends.shape[0]):
            for b in range(a):
                if np.hypot(*(ends[a] - ends[b])) <= join_m:
                    parent[root(a)] = root(b)
        roots = sorted({root(i) for i in range(ends.shape[0])})
        index = {r: k for k, r in enumerate(roots)}
        self.node = np.array([index[root(i)] for i in range(ends.shape[0])], dtype=np.int64).reshape(count, 2)
        members = [[(k, e) for k in range(count) for e in (0, 1) if self.node[k, e] == nd] for nd in range(len(roots))]
        self.adj_start = np.concatenate([[0], np.cumsum([len(m) for m in members])]).astype(np.int64)
        self.adj_way = np.array([k for m in members for k, _ in m], dtype=np.int64)
        self.adj_end = np.array([e for m in members for _, e in m], dtype=np.int64)

    def _doors(self, world: WorldConfig) -> NDArray[np.float64]:
        """``(D, 4)``: every building door's middle ``(x, y)``, outward heading and half width."""
        out = []
        for feature in world.features_of_type("buildings").values():
            default = getattr(feature, "facade", None)
            for building in getattr(feature, "items", ()):
                facade = building.facade or default
                half = 0.5 * (facade.door_size_m[0] if facade is not None else 1.8)
                out += [(x, y, heading, half) for x, y, heading in building.door_points()]
        return np.asarray(out, dtype=np.float64).reshape(-1, 4)

    @staticmethod
    def _solid_edges(world: WorldConfig) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.int64]]:
        """The floor-standing solids' edges (start ``(E, 2)``, direction ``(E, 2)``) and each
        solid's first edge ``(K,)``: a point is inside solid k when left of all its edges."""
        starts: list[NDArray[np.float64]] = []
        dirs: list[NDArray[np.float64]] = []
        firsts: list[int] = []
        for feature in world.features.values():
            for solid in feature.solids():
                if solid.bottom_m > 0.0:
                    continue
                corners = solid.corners
                firsts.append(sum(s.shape[0] for s in starts))
                starts.append(corners)
                dirs.append(np.roll(corners, -1, axis=0) - corners)
        if not starts:
            return np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(0, dtype=np.int64)
        return np.concatenate(starts), np.concatenate(dirs), np.asarray(firsts, dtype=np.int64)

    def _clear_state(self) -> None:
        w, s, cars = self.walkers, self.standing, self.cars
        self.way = np.zeros(w, dtype=np.int64)
        self.direction = np.ones(w)
        self.keep = np.zeros(w)
        self.desired_mps = np.full(w, self.c.walk_speed_mps[0])
        self.spot = np.zeros((s, 2))
        self.group_centre = np.zeros((len(self.sizes), 2))
        self.fidget = np.zeros((s, 2))
        self.next_fidget_s = np.zeros(s)
        self.lane = np.zeros(cars, dtype=np.int64)

    def bodies(self) -> list[BodySpec]:
        """People (``shape: person``) then cars (``shape: car``, sized by ``car``)."""
        c = self.c
        person = BodySpec("crowd", c.radius_m, c.mass_kg, shape="person", person=c.person)
        car = BodySpec("crowd", c.car.bounding_radius_m, c.car_mass_kg, shape="car", car=c.car)
        return [person] * self.first_car + [car] * (self.count - self.first_car)

    def start_headings(self) -> NDArray[np.float64]:
        return self._start_headings

    # ------------------------------------------------------------------ reset
    def reset(self, rng: np.random.Generator, taken: Taken) -> NDArray[np.float64]:
        self.held[:] = False
        self._clear_state()
        out = np.zeros((self.count, 2))
        headings = np.zeros(self.count)
        boxes: list[NDArray[np.float64]] = []  # the cars' footprints placed so far
        for k, (x, y, heading) in enumerate(self.parked_spots):
            out[self.first_parked + k] = (x, y)
            headings[self.first_parked + k] = heading
            boxes.append(self.c.car.footprint(x, y, heading))
        self._place_cars(rng, taken, boxes, out, headings)
        taken += [(float(x), float(y), float(self.c.car.bounding_radius_m)) for x, y in out[self.first_car :]]
        for g, size in enumerate(self.sizes):
            self.group_centre[g], self.spot[self.group_of == g] = self._place_group(rng, g, size, taken)
        out[self.walkers : self.first_car] = self.spot
        out[: self.walkers] = self._place_walkers(rng, taken)
        self.next_fidget_s = rng.uniform(*self.c.fidget_period_s, size=self.standing)
        self._start_headings = headings
        self.draw_seers(rng)  # the cars' entries are never read: cars stop for the robot (drive_velocities)
        return out

    def _free(self, xy: NDArray[np.float64], radius: float, taken: Taken) -> bool:
        """Whether a disc at ``xy`` overlaps nothing taken, no floor-standing segment, no solid, and is inside."""
        xmin, ymin, xmax, ymax = self.world_config.arena_m
        if not (xmin + radius <= xy[0] <= xmax - radius and ymin + radius <= xy[1] <= ymax - radius):
            return False
        if taken:
            t = np.asarray(taken, dtype=np.float64)
            if np.any(np.sum((t[:, :2] - xy) ** 2, axis=1) <= (t[:, 2] + radius + _PLACE_GAP_M) ** 2):
                return False
        a, d = self._seg[:, :2], self._seg[:, 2:] - self._seg[:, :2]
        if a.shape[0]:
            t = np.clip(np.einsum("ij,ij->i", xy - a, d) / np.maximum(np.einsum("ij,ij->i", d, d), 1e-12), 0.0, 1.0)
            if np.min(np.hypot(*(a + t[:, None] * d - xy).T)) < radius + _PLACE_GAP_M:
                return False
        starts, dirs, firsts = self._solids
        if firsts.size:
            rel = xy - starts
            left = dirs[:, 0] * rel[:, 1] - dirs[:, 1] * rel[:, 0]
            if np.any(np.minimum.reduceat(left, firsts) > 0.0):
                return False
        return True

    def _lane_shares(self) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
        """Each lane's usable length (m) and its number of moving cars (shared by length).

        Raises:
            ConfigError: if a lane has no room for its cars ``car_gap_m`` apart.
        """
        c = self.c
        usable = np.maximum(self.lanes.length - CAR_LEAVE_M, 0.0)
        quota = usable / usable.sum() * self.cars
        per_lane = np.floor(quota).astype(np.int64)
        for k in np.argsort(-(quota - per_lane), kind="stable")[: self.cars - int(per_lane.sum())]:
            per_lane[k] += 1
        need = c.car.length_m + c.car_gap_m
        for k, n in enumerate(per_lane):
            if n and usable[k] / n < need:
                raise ConfigError(
                    f"world {self.world_config.name!r}: lane {c.lanes[k].name or k!r} of crowd {self.name!r} "
                    f"({self.lanes.length[k]:.1f} m) has no room for {n} cars {c.car_gap_m:g} m apart "
                    f"({self.cars} of the crowd's {c.count} are cars); ask for fewer cars (count, car_share) or a "
                    "shorter car_gap_m"
                )
        return usable, per_lane

    def _place_cars(
        self,
        rng: np.random.Generator,
        taken: Taken,
        boxes: list[NDArray[np.float64]],
        out: NDArray[np.float64],
        headings: NDArray[np.float64],
    ) -> None:
        """The moving cars spread evenly along the lanes (by length), a random phase and jitter per lane."""
        c = self.c
        lanes = self.lanes
        if not self.cars:
            return
        usable, per_lane = self._lane_shares()
        need = c.car.length_m + c.car_gap_m
        car = self.first_car
        for k, n in enumerate(per_lane):
            if n == 0:
                continue
            spacing = usable[k] / n
            for _ in range(100):
                s = rng.uniform(0.0, spacing) + spacing * np.arange(n) + rng.uniform(0.0, spacing - need, size=n)
                s = np.sort(np.mod(s, usable[k]))
                placed = [lanes.at(k, float(v)) for v in s]
                new = [c.car.footprint(p[0], p[1], math.atan2(t[1], t[0])) for p, t in placed]
                if all(self._box_free(box, taken, boxes) for box in new):
                    break
            else:
                raise RuntimeError(
                    f"world {self.world_config.name!r}: no free spots on lane {c.lanes[k].name or k!r} for {n} cars of "
                    f"crowd {self.name!r}"
                )
            for (p, t), box in zip(placed, new):
                out[car] = p
                headings[car] = math.atan2(t[1], t[0])
                self.lane[car - self.first_car] = k
                boxes.append(box)
                car += 1

    def _box_free(self, box: NDArray[np.float64], taken: Taken, boxes: list[NDArray[np.float64]]) -> bool:
        """Whether a car footprint ``box`` clears every disc taken and every car placed."""
        if any(boxes_overlap(box, other, _PLACE_GAP_M) for other in boxes):
            return False
        return all(box_disc_gap(box, np.array([x, y])) > r + _PLACE_GAP_M for x, y, r in taken)

    def _place_group(
        self, rng: np.random.Generator, g: int, size: int, taken: Taken
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """A free spot for group ``g``: by a door (beside its way out), else beside a walkway."""
        c = self.c
        r = c.radius_m
        for _ in range(_PLACE_TRIES):
            ring = group_ring(size, c.group_spacing_m, rng.uniform(-math.pi, math.pi))
            ring_r = float(np.max(np.hypot(*ring.T))) + r
            side = 1.0 if rng.random() < 0.5 else -1.0
            if self.doors.shape[0]:
                x, y, heading, half = self.doors[rng.integers(self.doors.shape[0])]
                out = np.array([math.cos(heading), math.sin(heading)])
                along = np.array([-out[1], out[0]])
                centre = (
                    np.array([x, y])
                    + out * (rng.uniform(*c.door_distance_m) + ring_r)
                    + along * side * (half + rng.uniform(*c.door_side_m) + ring_r)
                )
            else:
                k = int(rng.choice(len(c.walkways), p=self.walkways.length / self.walkways.length.sum()))
                p, t = self.walkways.at(k, float(rng.uniform(0.0, self.walkways.length[k])))
                centre = p + side * np.array([-t[1], t[0]]) * (self.half_width[k] + ring_r + 0.3)
            people = centre + ring
            if not all(self._free(p, r, taken) for p in people):
                continue
            taken += [(float(px), float(py), r) for px, py in people]
            return centre, people
        raise RuntimeError(
            f"world {self.world_config.name!r}: no room for standing group {g} ({size} people) of crowd {self.name!r}; "
            "ask for fewer people in groups (group_share) or wider door_side_m"
        )

    def _place_walkers(self, rng: np.random.Generator, taken: Taken) -> NDArray[np.float64]:
        """Each walker at a random free spot of a walkway (by length), on its side of the centre line."""
        c = self.c
        w = self.walkers
        out = np.zeros((w, 2))
        if not w:
            return out
        ways = self.walkways
        p_way = ways.length / ways.length.sum()
        mean, sd = c.walk_speed_mps
        self.desired_mps = np.clip(rng.normal(mean, sd, size=w), *c.walk_speed_range_mps)
        self.keep = rng.uniform(*c.keep_right, size=w)
        for i in range(w):
            for _ in range(_PLACE_TRIES):
                k = int(rng.choice(len(p_way), p=p_way))
                direction = 1.0 if rng.random() < 0.5 else -1.0
                p, t = ways.at(k, float(rng.uniform(0.0, ways.length[k])))
                off = self.keep[i] * max(0.0, self.half_width[k] - c.radius_m - EDGE_GAP_M)
                xy = p + direction * off * np.array([t[1], -t[0]])
                if self._free(xy, c.radius_m, taken):
                    break
            else:
                raise RuntimeError(
                    f"world {self.world_config.name!r}: no free spot on the walkways for walker {i} of crowd {self.name!r} "
                    f"({w} walkers); ask for fewer (count)"
                )
            out[i] = xy
            self.way[i] = k
            self.direction[i] = direction
            taken.append((float(xy[0]), float(xy[1]), c.radius_m))
        return out

    # ------------------------------------------------------------------ every step
    def _views(self, state: WorldState, others: Rows) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
        """``(M,)`` each of ``others``' repulsion gain for walkers (the robot's, 0 for a car: its
        box repels, 1 for people) and ``(B,)`` each body's kind for the cars (cached)."""
        key = (state.body_count, others if isinstance(others, slice) else others.tobytes())
        if key != self._gain_key:
            rows = np.arange(state.body_count)
            car_rows = np.asarray(self.rows[self.first_car : self.count])
            kind = np.full(state.body_count, DISC, dtype=np.int64)
            kind[car_rows] = BOX
            self._kind = kind
            other_rows = rows[others]
            self._gain = np.where(other_rows == 0, self.c.robot_repulsion_gain, np.where(kind[other_rows] == BOX, 0.0, 1.0))
            self._gain_key = key
        return self._gain, self._kind

    def commands(self, state: WorldState, others: Rows, rng: np.random.Generator) -> Commands:
        c = self.c
        rows = self.member_rows
        pos = state.positions[rows]
        vel = state.velocities[rows]
        angles = state.angles[rows]
        w, fc, fp = self.walkers, self.first_car, self.first_parked
        out = np.zeros((self.count, 2))
        gain, kind = self._views(state, others)
        teleports: tuple[tuple[int, NDArray[np.float64]], ...] = ()
        headings: tuple[tuple[int, float], ...] = ()
        if w:
            ways = self.walkways
            out[:w] = walk_velocities(
                pos[:w], vel[:w], self.desired_mps, self.way, self.direction, self.keep, rng.random(w),
                ways.pts, ways.cum, ways.first, ways.n, ways.length, self.half_width,
                self.node, self.adj_start, self.adj_way, self.adj_end,
                state.positions[others], state.radii_m[others], gain,
                pos[fc:], angles[fc:], vel[fc:], self._car_halves,
                c.radius_m, c.lookahead_m, c.end_m, c.relaxation_s, c.repulsion_strength_mps2, c.repulsion_range_m,
                c.cutoff_ranges * c.repulsion_range_m, c.car_repulsion_gain, c.yield_s, self.dt_s,
            )  # fmt: skip
            if c.give_way:
                out[:w] = give_way(
                    pos[:w], out[:w], self.radii_m[:w], ~self.held[:w], state.positions[0], state.velocities[0],
                    state.robot_radius_m, c.give_way_margin_m, c.give_way_horizon_s,
                )  # fmt: skip
            self.react_to_robot(state, out, slice(0, w), SPEED_CAP * self.desired_mps, self.dt_s)
        if self.standing:
            refresh_fidgets(self.fidget, self.next_fidget_s, state.time_s, c.fidget_m, c.fidget_period_s, rng)
            out[w:fc] = seek(pos[w:fc], self.spot + self.fidget, self.max_speed[w:fc], self.held[w:fc], self.radii_m[w:fc])
            self.react_to_robot(state, out, slice(w, fc), self.max_speed[w:fc], SEEK_RELAXATION_S)
        if self.cars:
            lanes = self.lanes
            out[fc:fp], at_end = drive_velocities(
                pos[fc:fp], vel[fc:fp], angles[fc:fp], self.lane, self.held[fc:fp], self.rows[fc:fp],
                lanes.pts, lanes.cum, lanes.first, lanes.n, lanes.length,
                state.positions, state.velocities, state.radii_m, state.angles, kind,
                float(self.car_half[0]), float(self.car_half[1]), c.car_speed_mps, c.car_accel_mps2, c.car_brake_mps2,
                c.car_max_brake_mps2, c.car_gap_m, c.car_stop_gap_m, c.car_watch_margin_m, c.car_watch_s,
                c.car_lookahead_m, self.dt_s,
            )  # fmt: skip
            if at_end.any():
                teleports, headings = self._re_entries(state, np.flatnonzero(at_end), out, rng)
        if self.parked_count:
            back = (self.parked_spots[:, :2] - pos[fp:]) / self.dt_s
            speed = np.hypot(back[:, 0], back[:, 1])
            out[fp:] = back * np.minimum(1.0, _PARKED_RETURN_MPS / np.maximum(speed, 1e-12))[:, None]
        out[self.held] = 0.0
        return Commands(out, None, teleports, headings)

    def _re_entries(
        self, state: WorldState, leaving: NDArray[np.int64], out: NDArray[np.float64], rng: np.random.Generator
    ) -> tuple[tuple[tuple[int, NDArray[np.float64]], ...], tuple[tuple[int, float], ...]]:
        """Cars at their lane's end (``leaving``, indices among the moving cars) come back in at the
        start of a lane drawn at random among the free ones, facing along it at their speed; one
        finding none brakes (at ``car_max_brake_mps2``) and waits at the end."""
        c = self.c
        rows = self.member_rows
        pos, vel, angles = state.positions[rows], state.velocities[rows], state.angles[rows]
        cars_xy, cars_heading = pos[self.first_car :].copy(), angles[self.first_car :].copy()  # (updated as cars move)
        moves: list[tuple[int, NDArray[np.float64]]] = []
        turns: list[tuple[int, float]] = []
        for car in leaving:
            i = self.first_car + int(car)
            if self.held[i]:
                continue
            speed = float(np.hypot(*vel[i]))
            for k in rng.permutation(len(c.lanes)):
                p, t = self.lanes.at(int(k), 0.0)
                if self._start_free(state, i, p, t, speed, cars_xy, cars_heading):
                    break
            else:
                out[i] = vel[i] * max(0.0, 1.0 - c.car_max_brake_mps2 * self.dt_s / max(speed, 1e-9))
                continue
            heading = math.atan2(t[1], t[0])
            moves.append((i, p))
            turns.append((i, heading))
            self.lane[int(car)] = int(k)
            cars_xy[i - self.first_car], cars_heading[i - self.first_car] = p, heading
        return tuple(moves), tuple(turns)

    def _start_free(
        self,
        state: WorldState,
        member: int,
        start: NDArray[np.float64],
        tangent: NDArray[np.float64],
        speed: float,
        cars_xy: NDArray[np.float64],
        cars_heading: NDArray[np.float64],
    ) -> bool:
        """Whether a car entering at ``start`` along ``tangent`` at ``speed`` finds its way clear:
        no other car's box (the cars at ``cars_xy``, ``cars_heading``), nor the robot or a person,
        in the strip from just behind it to where it could stop ``car_gap_m`` short
        (``car_stop_gap_m`` for the robot and people)."""
        c = self.c
        hl, hw = float(self.car_half[0]), float(self.car_half[1])
        ahead = hl + max(c.car_gap_m, c.car_stop_gap_m) + speed * speed / (2.0 * c.car_brake_mps2)
        normal = np.array([-tangent[1], tangent[0]]) * (hw + CAR_SIDE_GAP_M)
        back, front = start - tangent * (hl + 0.5), start + tangent * ahead
        strip = np.array([back - normal, front - normal, front + normal, back + normal])
        centre = 0.5 * (back + front)
        reach = 0.5 * (ahead + hl + 0.5) + hw + c.car.bounding_radius_m
        near = np.flatnonzero(np.hypot(*(cars_xy - centre).T) <= reach)
        for j in near:
            if j + self.first_car == member:
                continue
            if boxes_overlap(strip, c.car.footprint(float(cars_xy[j, 0]), float(cars_xy[j, 1]), float(cars_heading[j])), 0.0):
                return False
        people = np.concatenate([[0], np.asarray(self.rows[: self.first_car])]).astype(np.int64)
        xy, r = state.positions[people], state.radii_m[people]
        close = np.hypot(*(xy - centre).T) <= reach
        return all(box_disc_gap(strip, p) > rr for p, rr in zip(xy[close], r[close]))

    # ------------------------------------------------------------------ drawing
    def facing_rad(self, state: WorldState) -> NDArray[np.float64]:
        """``(people,)`` where each person faces: a walker where it walks, a standing person its group's centre."""
        pos = state.positions[self.member_rows]
        vel = state.velocities[self.member_rows]
        w, fc = self.walkers, self.first_car
        out = np.arctan2(vel[:fc, 1], vel[:fc, 0])
        to_centre = self.group_centre[self.group_of] - pos[w:fc]
        out[w:fc] = np.arctan2(to_centre[:, 1], to_centre[:, 0])
        return out

    def draw(self, canvas: Any, state: WorldState) -> None:
        """People as discs (walkers and standing people in two shades) with a tick where they
        face, cars as their footprint boxes (moving and parked in two shades) with a line to the front."""
        rows = self.member_rows
        pos = state.positions[rows]
        facing = self.facing_rad(state)
        for i in range(self.first_car):
            (x, y), r, a = pos[i], float(self.radii_m[i]), float(facing[i])
            canvas.circle(x, y, r, self.fill if i < self.walkers else self.standing_fill, 0)
            canvas.circle(x, y, r, self.outline, 1)
            canvas.line((x, y), (x + r * math.cos(a), y + r * math.sin(a)), self.outline, 1)
        angles = state.angles[rows]
        for i in range(self.first_car, self.count):
            (x, y), heading = pos[i], float(angles[i])
            corners = self.c.car.footprint(float(x), float(y), heading)
            canvas.polygon(corners, CAR_FILL if i < self.first_parked else PARKED_FILL, 0)
            canvas.polygon(corners, self.outline, 1)
            canvas.line(0.5 * (corners[0] + corners[1]), (x, y), self.outline, 1)
