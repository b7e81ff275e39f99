"""The crowd plug-in interface: moving bodies with a behaviour, registered by type name.

A world YAML names its crowds as a mapping from name to a config tagged by ``type``::

    crowds:
      robots: {type: soccer, count: 6, ball: true}

Each crowd owns its bodies (members and, for the soccer crowd, the ball): it says what they
are (:class:`BodySpec`), where they start, and every step what they want to do
(:class:`Commands`), reading only a frozen :class:`~envs.state.WorldState`. The world turns
that into pymunk bodies and forces; bodies follow the robot in crowd order. ``crowd_size``
sets the count of the world's first crowd (its density). Built in: ``soccer``
(:mod:`.soccer`), ``queues`` (:mod:`.queues`), ``walkers`` (:mod:`.walkers`), ``corridor``
(:mod:`.corridor`), ``campus`` (:mod:`.campus`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, ClassVar, NamedTuple, TypeVar

import numpy as np
from numpy.typing import NDArray

from core.schema import check, is_real
from envs.bodies import CarConfig, PersonConfig
from envs.crowds.steering import draw_seers, see_robot
from envs.plugins import Entry, Registry
from envs.state import Rows, WorldState

if TYPE_CHECKING:
    from envs.config import WorldConfig

ConfigT = TypeVar("ConfigT", bound="CrowdConfig")

#: the vertical profiles a crowd's members may have (:mod:`envs.bodies`)
MEMBER_SHAPES = ("column", "person", "car")

#: a member's body as the crowd sees it: (x, y, radius) already taken at placement time
Taken = list[tuple[float, float, float]]


@dataclass(frozen=True)
class CrowdConfig:
    """Base of every crowd config: ``count`` members of one size and weight.

    Loaded from a mapping whose ``type`` names a registered crowd type; the other entries
    are that type's fields, checked by the strict loader.

    ``shape`` is the members' vertical profile (:mod:`envs.bodies`): ``"column"``, a disc of
    ``radius_m`` up to ``height_m`` (a robot), ``"person"``, legs, torso and head sized by
    ``person``, whose footprint disc of ``radius_m`` is what collides either way, or ``"car"``,
    a body and wheels sized by ``car``, whose footprint box collides; a car's ``radius_m`` is
    the disc its neighbours keep clear of when they steer and are placed, so it must cover
    the box (at least ``car.bounding_radius_m``).
    """

    type_name: ClassVar[str] = ""
    #: the fields that may be ``inf`` (:func:`envs.config.non_finite_numbers`): a column taller than any sensor
    unbounded_fields: ClassVar[frozenset[str]] = frozenset({"height_m"})
    count: int = 0
    max_count: int = 14
    radius_m: float = 0.25
    mass_kg: float = 30.0
    speed_mps: float = 1.75
    shape: str = "column"
    height_m: float = math.inf  # a column's height (inf: taller than any sensor)
    person: PersonConfig = field(default_factory=PersonConfig)  # body sizes and gait when shape is "person"
    car: CarConfig = field(default_factory=CarConfig)  # body and wheels when shape is "car"

    @classmethod
    def __from_config__(cls, value: Any, where: str) -> CrowdConfig:
        """Build the config of the type named by ``value["type"]`` (the strict loader's hook)."""
        return CROWDS.config_from(value, where)

    def __post_init__(self) -> None:
        check(self.max_count >= 0, f"crowd.max_count must be >= 0, got {self.max_count}")
        check(0 <= self.count <= self.max_count, f"crowd.count must be in [0, {self.max_count}], got {self.count}")
        check(self.radius_m > 0, f"crowd.radius_m must be > 0, got {self.radius_m}")
        check(self.mass_kg > 0, f"crowd.mass_kg must be > 0, got {self.mass_kg}")
        check(self.speed_mps > 0, f"crowd.speed_mps must be > 0, got {self.speed_mps}")
        check(self.shape in MEMBER_SHAPES, f"crowd.shape must be one of {', '.join(MEMBER_SHAPES)}, got {self.shape!r}")
        check(self.height_m > 0, f"crowd.height_m must be > 0, got {self.height_m}")
        check(
            self.shape != "car" or self.radius_m >= self.car.bounding_radius_m,
            f"crowd.radius_m {self.radius_m} is too small for shape 'car': it must cover the car's footprint box "
            f"({self.car.length_m} x {self.car.width_m} m), at least car.bounding_radius_m {self.car.bounding_radius_m:.4g}",
        )

    def top_speeds(self) -> tuple[tuple[str, float, float], ...]:
        """``(body, top speed m/s, radius m)`` of each kind of body this crowd moves.

        The world bounds its ``dt_s`` by these (:class:`~envs.config.WorldConfig`): no body may
        travel more than its own radius in one step. The base crowd's members seek at up to
        ``speed_mps``; a crowd type whose bodies move by other fields overrides this.
        """
        return (("members", self.speed_mps, self.radius_m),)


@dataclass(frozen=True)
class PeopleConfig(CrowdConfig):
    """Base of the crowds of people (queues, walkers, corridor, campus): ``sees_robot``.

    ``sees_robot`` is the share of the crowd's people who see our robot, drawn per member and
    episode (:func:`envs.crowds.steering.draw_seers`). One who sees it reacts as a pedestrian
    does (:func:`envs.crowds.steering.see_robot`, CrowdNav's "visible robot"): a social force
    from the robot's disc, and stepping aside, slowing or waiting when contact is near. The
    others treat it as the crowd always has (0: the invisible robot, CrowdNav's other setting,
    for studies of inattentive crowds). The default is 1: everyone sees it.
    """

    sees_robot: float = 1.0

    def __post_init__(self) -> None:
        super().__post_init__()
        value = self.sees_robot
        check(
            is_real(value) and 0.0 <= value <= 1.0,
            f"{self.type_name or 'crowd'}.sees_robot must be a share in [0, 1] (0: nobody sees the robot, 1: everyone), got {value!r}",
        )


@dataclass(frozen=True)
class BodySpec:
    """One body of a crowd.

    Attributes:
        kind: ``"crowd"`` (a member: robot, person; force-driven toward the velocity the crowd
            wants) or ``"ball"`` (its velocity is set directly); also the contact kind.
        radius_m, mass_kg: the footprint disc (a car's: the disc around its box) and its mass.
        occludes: whether it blocks a camera's sight lines.
        friction, elasticity: pymunk shape settings.
        shape: its vertical profile (:data:`envs.bodies.SHAPES`): ``"column"`` up to
            ``height_m``, ``"ball"`` (a sphere of ``radius_m``), ``"person"`` sized by ``person``
            or ``"car"`` sized by ``car`` (its footprint box collides, not the disc).
    """

    kind: str
    radius_m: float
    mass_kg: float
    occludes: bool = True
    friction: float = 0.5
    elasticity: float = 0.0
    shape: str = "column"
    height_m: float = math.inf
    person: PersonConfig | None = None
    car: CarConfig | None = None

    def __post_init__(self) -> None:
        check(self.shape != "person" or self.person is not None, "BodySpec: shape 'person' needs person sizes (a PersonConfig)")
        check(self.shape != "car" or self.car is not None, "BodySpec: shape 'car' needs car sizes (a CarConfig)")

    @property
    def sizes(self) -> PersonConfig | CarConfig | None:
        """What its shape is sized by (:data:`envs.bodies.Sizes`)."""
        return self.person if self.shape == "person" else self.car if self.shape == "car" else None


class Commands(NamedTuple):
    """What a crowd wants this step (a named tuple: one is made per crowd and step).

    Attributes:
        member_velocity: ``(M, 2)`` desired velocities of its members (in body order).
        ball_velocity: ``(2,)`` the ball's velocity to set, or None (no ball, or leave it).
        teleports: ``(body index within the crowd, (x, y))`` to move before the step (a ball put back in play).
        headings: ``(body index within the crowd, heading rad)`` to turn to before the step, its
            turn rate 0 this step; one also teleported keeps its speed, along its new heading,
            with no driving force this step (a car re-entering the campus drives on).
    """

    member_velocity: NDArray[np.float64]
    ball_velocity: NDArray[np.float64] | None = None
    teleports: tuple[tuple[int, NDArray[np.float64]], ...] = ()
    headings: tuple[tuple[int, float], ...] = ()


class Crowd:
    """Base crowd: ``count`` members of one size; subclasses add behaviour (and maybe a ball).

    Attributes:
        name: the crowd's name in the world config.
        config: its config.
        rows: the world's body rows of its bodies (set by the world), members first.
        member_rows: the rows of its members only (a slice: they are consecutive).
        held: ``(M,)`` members frozen in place by a scripted driver.
        member_mass_kg: ``(M,)`` each member's mass (``mass_kg`` for all by default; a crowd of
            people and cars sets its own), which the world's driving forces use.
    """

    fill: tuple[int, int, int] = (60, 60, 60)
    outline: tuple[int, int, int] = (10, 10, 10)

    def __init__(self, name: str, config: CrowdConfig, world: WorldConfig) -> None:
        self.name = name
        self.config = config
        self.world_config = world
        self.size_members(int(config.count))
        self.rows = np.zeros(0, dtype=np.int64)
        self.member_rows = slice(0, 0)

    def size_members(self, count: int) -> None:
        """Make the per-member arrays for ``count`` members of the config's size, speed and mass
        (a crowd with members besides ``config.count``, such as standing groups, calls it again)."""
        c = self.config
        self.count = count
        self.radii_m = np.full(count, c.radius_m)
        self.held = np.zeros(count, dtype=np.bool_)
        self.max_speed = np.full(count, c.speed_mps)
        self.member_mass_kg = np.full(count, c.mass_kg)
        self.sees = np.zeros(count, dtype=np.bool_)  # who sees our robot (draw_seers)
        self.any_sees = False

    def bodies(self) -> list[BodySpec]:
        """The crowd's bodies, members first (override to add a ball or other bodies)."""
        c = self.config
        person = c.person if c.shape == "person" else None
        car = c.car if c.shape == "car" else None
        return [
            BodySpec("crowd", float(r), c.mass_kg, shape=c.shape, height_m=c.height_m, person=person, car=car)
            for r in self.radii_m
        ]

    def attach(self, rows: NDArray[np.int64]) -> None:
        """Called by the world with the rows of :meth:`bodies`."""
        self.rows = np.asarray(rows, dtype=np.int64)
        first = int(self.rows[0]) if self.rows.size else 0
        self.member_rows = slice(first, first + self.count)  # a slice: views, no copies per step

    def check_member(self, index: int) -> None:
        """Raise :class:`IndexError` unless ``index`` is one of the crowd's members."""
        if not 0 <= index < self.count:
            raise IndexError(f"crowd {self.name!r}: member {index} does not exist (it has {self.count})")

    def hold(self, index: int, flag: bool) -> None:
        """Freeze member ``index`` in place (``flag``) or let it move again."""
        self.check_member(index)
        self.held[index] = flag

    def reset(self, rng: np.random.Generator, taken: Taken) -> NDArray[np.float64]:
        """``(bodies, 2)`` start positions; append the members placed to ``taken`` (x, y, r)."""
        self.held[:] = False
        return np.zeros((len(self.bodies()), 2))

    def start_headings(self) -> NDArray[np.float64] | None:
        """``(bodies,)`` the headings of the bodies the last :meth:`reset` placed (cars along their
        lane, parked cars as parked), or None: every body starts facing +x (heading 0)."""
        return None

    def commands(self, state: WorldState, others: Rows, rng: np.random.Generator) -> Commands:
        """What the crowd wants this step; ``others``: the rows of every member of every crowd."""
        return Commands(np.zeros((self.count, 2)))

    def draw_seers(self, rng: np.random.Generator) -> None:
        """Draw who sees the robot this episode (``sees``, ``(members,)``) from the config's
        ``sees_robot`` share (a crowd of people calls it at its reset; nobody otherwise)."""
        share = float(getattr(self.config, "sees_robot", 0.0))
        self.sees = draw_seers(rng, self.count, share)
        self.any_sees = bool(self.sees.any())

    def react_to_robot(
        self, state: WorldState, want: NDArray[np.float64], people: slice, top_speed: NDArray[np.float64], force_s: float
    ) -> None:
        """Members ``people`` (a slice of the members) who see the robot react to it: their rows of
        ``want`` ``(members, 2)`` change in place (:func:`envs.crowds.steering.see_robot`;
        ``top_speed``: theirs, ``force_s``: how long the robot's force acts on ``want``)."""
        if not self.any_sees:
            return
        want[people] = see_robot(
            state.positions[self.member_rows][people],
            want[people],
            self.radii_m[people],
            self.sees[people] & ~self.held[people],
            top_speed,
            state.positions[0],
            state.velocities[0],
            state.robot_radius_m,
            force_s,
        )

    def draw(self, canvas: Any, state: WorldState) -> None:
        """Draw the crowd's bodies: members as filled, outlined discs, cars as their footprint boxes."""
        rows = self.member_rows
        if self.config.shape == "car":
            for (x, y), heading in zip(state.positions[rows], state.angles[rows]):
                corners = self.config.car.footprint(float(x), float(y), float(heading))
                canvas.polygon(corners, self.fill, 0)
                canvas.polygon(corners, self.outline, 1)
                canvas.line(0.5 * (corners[0] + corners[1]), (x, y), self.outline, 1)  # the front
            return
        for xy, r in zip(state.positions[rows], state.radii_m[rows]):
            canvas.circle(xy[0], xy[1], r, self.fill, 0)
            canvas.circle(xy[0], xy[1], r, self.outline, 1)

    # ------------------------------------------------------------------ helpers
    def field_box(self, margin: float) -> tuple[float, float, float, float]:
        xmin, ymin, xmax, ymax = self.world_config.field_m
        return (xmin + margin, ymin + margin, xmax - margin, ymax - margin)

    def free_positions(
        self,
        rng: np.random.Generator,
        count: int,
        radius: float,
        taken: Taken,
        box: tuple[float, float, float, float] | None = None,
    ) -> NDArray[np.float64]:
        """``count`` random positions that overlap nothing in ``taken`` (x, y, r), appended to it.

        The centres are drawn uniformly in ``box`` (xmin, ymin, xmax, ymax), by default the
        field less ``radius`` (:meth:`field_box`).
        """
        x0, y0, x1, y1 = self.field_box(radius) if box is None else box
        check(
            count == 0 or (x0 <= x1 and y0 <= y1),
            f"world {self.world_config.name!r}: crowd {self.name!r}: members of radius {radius:g} m do not fit in the space "
            f"where their centres are drawn, x [{x0:g}, {x1:g}], y [{y0:g}, {y1:g}] (the region less the radius); "
            "give a smaller radius_m",
        )
        out = np.zeros((count, 2))
        for i in range(count):
            for _ in range(1000):
                p = rng.uniform((x0, y0), (x1, y1))
                if all((p[0] - x) ** 2 + (p[1] - y) ** 2 > (r + radius + 0.05) ** 2 for x, y, r in taken):
                    break
            else:
                raise RuntimeError(
                    f"world {self.world_config.name!r}: no free space for {count} members of crowd {self.name!r} "
                    f"(radius {radius} m)"
                )
            out[i] = p
            taken.append((float(p[0]), float(p[1]), radius))
        return out


#: builds a crowd from its name, its config and the world config
CrowdFactory = Callable[[str, Any, "WorldConfig"], Crowd]
CrowdType = Entry[CrowdConfig, CrowdFactory]

#: the registered crowd types
CROWDS: Registry[CrowdConfig, CrowdFactory] = Registry("crowd", CrowdConfig)


def register_crowd(type_name: str, config_cls: type[ConfigT]) -> Callable[[type[Any]], type[Any]]:
    """Class decorator: register a :class:`Crowd` subclass (``cls(name, config, world)``) under ``type_name``."""
    return CROWDS.decorator(type_name, config_cls)


def crowd_types() -> list[str]:
    """The registered crowd type names, sorted."""
    return CROWDS.names()


def build_crowd(name: str, config: CrowdConfig, world: WorldConfig) -> Crowd:
    """The crowd ``config`` describes, named ``name``."""
    return CROWDS.get(config.type_name, f"crowd {name!r}").build(name, config, world)
