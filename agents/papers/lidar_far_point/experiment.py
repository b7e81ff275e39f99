"""The experiment as we set it up: our choices, the MCL configurations, the plan and the square path.

The paper's own numbers come from :mod:`.paper`; the world's and the localizers' shipped
settings from :mod:`.world`. What is defined here is ours (each constant says why).
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any

from agents.experiments.scenarios import OpenLoopDriver, square_driver
from agents.policies.paths import polygon_commands, square_vertices

from . import world
from .paper import HIT_SWEEP_SAMPLING, HITS, LAPS, REFERENCE_LIDAR_HEIGHT_M, SAMPLINGS, SPEED_MPS, UPDATE_TRAVEL_M

Params = tuple[tuple[str, Any], ...]

ENV_ID = "crowdloc/CrowdedRoom-v0"
CENTER_XY = (3.5, 3.5)  # the middle of the 7 m x 7 m room
SIDE_M = 2.5  # ours: fits between the queues (1.32 m clear of the queued bodies); 10 m per lap
TURN_RATE_RPS = 0.5  # ours (turns in place; the paper does not say)
CROWD_SIZE = 16  # the world's default: 8 people per queue
PILOT_SEEDS = (100, 103)  # the pilot that set SIDE_M and DENSITY_PARAMS (first and last seed)
#: ours: the MCL weighs a scan every 0.5 m of travel only (paper B); turning in place at the
#: corners (pi/2 between two updates at most) must not trigger extra updates.
UPDATE_MIN_ROTATION_RAD = 2.0 * math.pi
WORKS_FAILURE_RATE = 0.01  # ours: a configuration "works" when < 1 % of its estimates fail
WALL_TOL_M = 0.1  # ours: a beam is "on the wall" when within this of the empty room's range
SAMPLING_SWEEP_HIT_M = 0.2  # the hit sd of the sampling sweep (the MCL's shipped default)
DENSITIES = (0, 8, 16, 24, 30)
#: the fixed configuration of the crowd-size sweep (ours; see :func:`density_note`)
DENSITY_PARAMS: Params = (("sampling", 0.5), ("hit_std_m", 0.5))
#: the configuration of the real ``far_point_mcl`` pass (the MCL's shipped defaults)
PASS_PARAMS: Params = (("sampling", 0.1), ("hit_std_m", 0.2))
#: the reference LIDAR the paper put above the crowd, added to the room under this name through
#: the env's ``sensors`` keyword (:func:`env_kwargs`); the LIDAR under test is the room's own
REFERENCE_SENSOR = "lidar_top"
#: ours: the reference pose is ``mcl_lidar`` on the reference LIDAR's scans with its shipped
#: parameters (the paper's MCL: the beam model; the paper does not say how its reference MCL
#: was set), on the experiment's update schedule, from the known start pose
REFERENCE_MCL_PARAMS: Params = ()
REFERENCE_LOCALIZER = "mcl_lidar"  # the registered localizer of the reference pass
REFERENCE_RNG_SALT = 0x70F  # ours: the reference MCL's own generator, independent of the configurations'
AMCL_LF: Params = (
    ("model", "likelihood_field"), ("z_hit", 0.5), ("z_short", 0.0), ("z_max", 0.0), ("z_rand", 0.5), ("hit_std_m", 0.2),
)  # fmt: skip
#: name -> parameters of the AMCL-like rows; ``ros_amcl`` is ROS amcl's defaults beside it:
#: odom_alpha1..4 = 0.2 (sampling 1.0 on our base alphas), laser_max_beams 30 (every 37th beam)
AMCL_ROWS: tuple[tuple[str, Params], ...] = (
    ("amcl_like", (*AMCL_LF, ("sampling", 0.1))),
    ("ros_amcl", (*AMCL_LF, ("sampling", 1.0), ("beam_stride", 37))),
)
RNG_SALT = 0xFA5  # the localizers' generator: [seed, crowd size, salt], the same for every configuration

DEFAULT_SEEDS = 10
#: ``--quick``: at most this many seeds, one lap, three values per sweep, three crowd sizes
QUICK_SEEDS = 2
QUICK_LAPS = 1
QUICK_SAMPLINGS = (0.1, 0.6, 1.0)
QUICK_HITS = (0.2, 0.8, 1.0)
QUICK_DENSITIES = (0, CROWD_SIZE, 30)
QUICK_CHUNK = 4


def density_note() -> str:
    """The crowd-size sweep's configuration, in words."""
    p = dict(DENSITY_PARAMS)
    return f"sampling {p['sampling']:g}, hit {p['hit_std_m']:g} m: the middle of both sweeps"


# ------------------------------------------------------------------------------------ configurations


@dataclass(frozen=True)
class Config:
    """One MCL configuration.

    Attributes:
        far: fed the far-point scans (``far_point_mcl``) instead of the raw ones (``mcl_lidar``).
        params: ``LidarMCLParams`` overrides on top of the experiment's update schedule.
    """

    far: bool
    params: Params

    @property
    def key(self) -> str:
        body = ",".join(f"{k}={v}" for k, v in sorted(self.params))
        return f"{'far' if self.far else 'raw'}[{body}]"

    @property
    def variant(self) -> str:
        return VARIANTS[self.far]

    @property
    def localizer(self) -> str:
        """The registered localizer the configuration stands for (``far_point_mcl`` or ``mcl_lidar``)."""
        return "far_point_mcl" if self.far else "mcl_lidar"

    def mcl_params(self) -> dict[str, Any]:
        """The ``mcl_lidar`` overrides: the experiment's update schedule and :data:`AS_IN_PAPER`, then ``params``."""
        schedule = {"update_min_travel_m": UPDATE_TRAVEL_M, "update_min_rotation_rad": UPDATE_MIN_ROTATION_RAD}
        return {**schedule, **AS_IN_PAPER, **dict(self.params)}


VARIANTS = {False: "MCL only (raw scan)", True: "MCL + far points"}
#: the paper's plain MCL answers at every update: crowdloc's lost detection, claim limit and
#: recovery (ours: ``lost_ratio``, ``max_spread_m``, ``recovery``) are off, so errors are
#: taken over every update of the paper's method
AS_IN_PAPER: dict[str, Any] = {"lost_ratio": 0.0, "max_spread_m": math.inf, "recovery": False}

Pair = tuple[Config, Config]


def normalized(params: Iterable[tuple[str, Any]]) -> Params:
    """Parameters in key order (one key per configuration, whatever the order given)."""
    return tuple(sorted(dict(params).items()))


def both(params: Iterable[tuple[str, Any]]) -> Pair:
    """The configuration without and with the far-point processing."""
    p = normalized(params)
    return Config(False, p), Config(True, p)


def pass_config() -> Config:
    """The configuration of the real ``far_point_mcl`` pass."""
    return Config(True, normalized(PASS_PARAMS))


def reference_mcl_params() -> dict[str, Any]:
    """The reference ``mcl_lidar``'s overrides: the experiment's update schedule, then ``REFERENCE_MCL_PARAMS``."""
    return Config(False, normalized(REFERENCE_MCL_PARAMS)).mcl_params()


def sampling_params(sampling: float) -> Params:
    return (("sampling", sampling), ("hit_std_m", SAMPLING_SWEEP_HIT_M))


def hit_params(hit_std_m: float) -> Params:
    return (("sampling", HIT_SWEEP_SAMPLING), ("hit_std_m", hit_std_m))


# ------------------------------------------------------------------------------------ plan


@dataclass(frozen=True)
class Plan:
    """How much to run."""

    seeds: int
    laps: int
    samplings: tuple[float, ...]
    hits: tuple[float, ...]
    densities: tuple[int, ...]
    chunk: int = 8
    quick: bool = False

    def sampling_configs(self) -> list[tuple[float, Pair]]:
        return [(s, both(sampling_params(s))) for s in self.samplings]

    def hit_configs(self) -> list[tuple[float, Pair]]:
        return [(h, both(hit_params(h))) for h in self.hits]

    def amcl_configs(self) -> list[tuple[str, Pair]]:
        """``(row name, pair)`` of the AMCL-like rows."""
        return [(name, both(params)) for name, params in AMCL_ROWS]

    def main_configs(self) -> list[Config]:
        """Every configuration run at the paper's crowd size, each once."""
        out: dict[str, Config] = {}
        pairs = [p for _, p in self.sampling_configs()] + [p for _, p in self.hit_configs()]
        pairs += [p for _, p in self.amcl_configs()] + [both(DENSITY_PARAMS), both(PASS_PARAMS)]
        for pair in pairs:
            for c in pair:
                out.setdefault(c.key, c)
        return list(out.values())


def make_plan(args: argparse.Namespace) -> Plan:
    if args.quick:
        return Plan(min(args.seeds, QUICK_SEEDS), QUICK_LAPS, QUICK_SAMPLINGS, QUICK_HITS, QUICK_DENSITIES,
                    chunk=QUICK_CHUNK, quick=True)  # fmt: skip
    return Plan(args.seeds, LAPS, SAMPLINGS, HITS, DENSITIES)


# ------------------------------------------------------------------------------------ the square path


def perimeter_m() -> float:
    """Path length of one lap of the square."""
    return 4 * SIDE_M


def corners() -> list[tuple[float, float]]:
    """The square's corners, counter-clockwise from the start."""
    return square_vertices(CENTER_XY, SIDE_M)


def start_pose() -> tuple[float, float, float]:
    """The lower-left corner of the square, facing +x."""
    x, y = corners()[0]
    return (x, y, 0.0)


def reference_lidar() -> dict[str, Any]:
    """The reference LIDAR's fields: the room's LIDAR (fov, beams, range, noise) at the paper's reference height."""
    lidar = world.lidar()
    return {
        "type": "lidar", "key": REFERENCE_SENSOR, "height_m": REFERENCE_LIDAR_HEIGHT_M, "fov_rad": lidar.fov_rad,
        "beams": lidar.beams, "max_range_m": lidar.max_range_m, "range_std_m": lidar.range_std_m,
    }  # fmt: skip


def env_kwargs(crowd_size: int, steps: int) -> dict[str, Any]:
    """``gym.make`` arguments of the experiment's room: its crowd size, the time limit and the reference LIDAR."""
    return {"crowd_size": crowd_size, "max_episode_steps": steps, "sensors": {REFERENCE_SENSOR: reference_lidar()}}


def driver_factory(laps: int) -> Callable[[Any], OpenLoopDriver]:
    """``env -> driver`` of ``laps`` laps of the square (:func:`agents.experiments.scenarios.square_driver`)."""

    def make(env: Any) -> OpenLoopDriver:
        return square_driver(env, center_xy=CENTER_XY, side_m=SIDE_M, laps=laps, speed_mps=SPEED_MPS, turn_rate_rps=TURN_RATE_RPS)

    return make


def episode_steps(laps: int) -> int:
    """Steps of ``laps`` laps of the square at the world's time step."""
    lap = polygon_commands(corners(), 0.0, speed_mps=SPEED_MPS, turn_rate_rps=TURN_RATE_RPS, dt_s=world.room().dt_s)
    return laps * sum(c.steps for c in lap)
