"""The experimental conditions the report states, read from the config objects the runs used.

Nothing here restates a parameter: the worlds come from :meth:`jobs.Job.world` (the shipped
world plus each job's overrides), the localizer parameters from their shipped YAMLs
(:func:`jobs.shipped`), the scenario drivers' settings from :mod:`agents.experiments.scenarios`, and
the rest from the constants of :mod:`jobs`. Derived geometry (which stretch of the Exp 1
path sees the corner pole, the angle the goal posts subtend) is computed from those.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from agents.papers.bearing_candidates.jobs import BASELINES, EXP1_PAIR, STUDIES, Job, shipped
from agents.papers.world_text import odometry_text
from envs.crowds import SoccerConfig
from envs.sensors import BearingCameraConfig, OdometryConfig

if TYPE_CHECKING:
    from envs.config import WorldConfig


def cyclic_stretch(names: Sequence[str], members: Sequence[bool]) -> str:
    """The path stretch through the member vertices, from the vertex before the first one:
    ``"d-e-f"`` for members e and f of the loop a..h (one contiguous run assumed)."""
    n = len(names)
    start = next(i for i in range(n) if members[i] and not members[i - 1])
    stretch = [names[start - 1]]
    k = start
    while members[k % n] and len(stretch) <= n:
        stretch.append(names[k % n])
        k += 1
    return "-".join(stretch)


def eq1_error_sigmas(landmarks: int) -> float:
    """Expected eq. (1) error per frame of the true candidate, in bearing-noise sigmas:
    ``n`` terms ``|e_k|`` and ``n (n - 1) / 2`` pair terms ``|e_j - e_k|`` of Gaussian errors
    (``E|e| = sigma sqrt(2 / pi)``; a pair difference has sd ``sqrt(2) sigma``)."""
    pairs = landmarks * (landmarks - 1) / 2
    return math.sqrt(2.0 / math.pi) * (landmarks + pairs * math.sqrt(2.0))


@dataclass(frozen=True)
class Mark:
    """A landmark as the report names it."""

    name: str
    x_m: float
    y_m: float
    max_range_m: float


@dataclass(frozen=True)
class Exp1Geometry:
    """Where the Exp 1 path sees what.

    Attributes:
        pole: the range-limited landmark (the corner pole).
        posts: the pair method (5) is fed (the goal posts).
        loop: the path's vertex names, closed (``"a-b-...-h-a"``).
        pole_seen, pole_unseen: the stretches with the pole within / beyond its range.
        far: the stretch through the vertices farthest from the posts.
        far_m: the distance from those vertices to the nearer post.
        posts_apart_m: the posts' distance.
        subtended_deg: the angle the posts subtend at the farthest vertex.
    """

    pole: Mark
    posts: tuple[Mark, ...]
    loop: str
    pole_seen: str
    pole_unseen: str
    far: str
    far_m: float
    posts_apart_m: float
    subtended_deg: float


def exp1_geometry(world: WorldConfig, vertices: Mapping[str, tuple[float, float]]) -> Exp1Geometry:
    """The Exp 1 path (``vertices``) against the world's landmarks."""
    names = list(vertices)
    xy = np.array(list(vertices.values()), dtype=np.float64)
    marks = [Mark(lm.name, lm.x_m, lm.y_m, lm.max_range_m) for lm in world.landmarks]
    pole = next(lm for lm in marks if math.isfinite(lm.max_range_m))
    posts = tuple(marks[i] for i in EXP1_PAIR)
    seen = np.hypot(xy[:, 0] - pole.x_m, xy[:, 1] - pole.y_m) <= pole.max_range_m
    to_posts = np.array([np.hypot(xy[:, 0] - p.x_m, xy[:, 1] - p.y_m) for p in posts])  # (posts, vertices)
    nearer = to_posts.min(axis=0)
    far = np.isclose(nearer, nearer.max())
    v = xy[int(np.argmax(far))]
    a, b = (math.atan2(p.y_m - v[1], p.x_m - v[0]) for p in posts[:2])
    return Exp1Geometry(
        pole=pole,
        posts=posts,
        loop="-".join([*names, names[0]]),
        pole_seen=cyclic_stretch(names, list(seen)),
        pole_unseen=cyclic_stretch(names, list(~seen)),
        far=cyclic_stretch(names, list(far)),
        far_m=float(nearer.max()),
        posts_apart_m=math.hypot(posts[0].x_m - posts[1].x_m, posts[0].y_m - posts[1].y_m),
        subtended_deg=abs(math.degrees(math.remainder(a - b, math.tau))),
    )


@dataclass(frozen=True)
class Keeper:
    """Where the goalkeeper plays: the line it runs along and the x range it tracks the ball in."""

    y_m: float
    x_m: tuple[float, float]


def soccer_config(world: WorldConfig) -> SoccerConfig:
    """The world's soccer crowd config, or a ValueError."""
    found = [c for c in world.crowds.values() if isinstance(c, SoccerConfig)]
    if not found:
        raise ValueError(f"world {world.name!r} has no soccer crowd")
    return found[0]


def keeper(world: WorldConfig) -> Keeper:
    """The keeper's line, in front of its posts by the world's keeper offset."""
    soccer = soccer_config(world)
    if soccer.keeper_posts is None:
        raise ValueError(f"world {world.name!r} has no keeper posts")
    (x1, y1), (x2, y2) = soccer.keeper_posts
    into_field = -1.0 if y1 >= world.size_m[1] / 2 else 1.0
    return Keeper(y_m=y1 + into_field * soccer.keeper_offset_m, x_m=(min(x1, x2), max(x1, x2)))


@dataclass(frozen=True)
class WorldFacts:
    """What the report says about one study's world (as its env ran with it)."""

    size_m: tuple[float, float]
    landmarks: int
    landmark_names: tuple[str, ...]
    odometry_alphas: tuple[float, float, float, float]
    odometry: str  # its errors in words (agents.papers.world_text.odometry_text)
    slip_probability: float
    camera_noise_deg: float
    dropout: float  # camera dropout probability
    false_rate: float  # camera false-detection probability per slot and frame
    distractors: int  # objects of a landmark's colour beyond the field (persistent false detections)
    crowd: int  # crowd robots besides ours
    max_speed_mps: float  # our robot's command limit
    dt_s: float
    keeper: Keeper | None  # the goalkeeper's line, when the crowd's first member keeps goal


def world_facts(world: WorldConfig) -> WorldFacts:
    """The facts of ``world``."""
    camera = world.sensor_of_type("bearing_camera")
    odometry = world.sensor_of_type("odometry")
    if not isinstance(camera, BearingCameraConfig) or not isinstance(odometry, OdometryConfig):
        raise ValueError(f"world {world.name!r} has no bearing camera or no odometry")
    soccer = soccer_config(world)
    has_keeper = soccer.goalkeeper and soccer.count > 0
    return WorldFacts(
        size_m=(float(world.size_m[0]), float(world.size_m[1])),
        landmarks=len(world.landmarks),
        landmark_names=tuple(lm.name for lm in world.landmarks),
        odometry_alphas=odometry.alphas,
        odometry=odometry_text(odometry, world.robot),
        slip_probability=world.robot.slip_probability,
        camera_noise_deg=math.degrees(camera.noise_std_rad),
        dropout=camera.dropout_probability,
        false_rate=camera.false_detection_probability,
        distractors=len(camera.distractors),
        crowd=soccer.count,
        max_speed_mps=world.robot.max_speed_mps,
        dt_s=world.dt_s,
        keeper=keeper(world) if has_keeper and soccer.keeper_posts is not None else None,
    )


@dataclass(frozen=True)
class Shipped:
    """The shipped localizer parameters the report quotes (``configs/localizers/*.yaml``)."""

    cs_max_sets: int
    cs_prune_rad: float
    cs_abort_rad: float
    cs_determine_below: int
    cs_max_live_candidates: int
    kalman_vision_position_std_m: float
    mcl_paper_gate_rad: float


@dataclass(frozen=True)
class Kicks:
    """The Exp 2 driver's plays (:class:`agents.experiments.scenarios.SoccerDriver`)."""

    spread_deg: float  # kick-out direction: uniform within this of -y
    speed_mps: tuple[float, float]  # kick-out speed range
    shot_speed_mps: float
    after_shot_s: float  # the next play starts this long after a shot


@dataclass(frozen=True)
class Conditions:
    """What the runs were set up with.

    Attributes:
        worlds: study -> the facts of the world its env ran with (the first job's; a swept
            study's points differ only in the swept value).
        exp1: the Exp 1 path against its landmarks.
        shipped: the localizer parameters quoted.
        kicks: the Exp 2 driver's settings.
        known_start: labels of the baselines that get the known start pose.
    """

    worlds: dict[str, WorldFacts]
    exp1: Exp1Geometry | None
    shipped: Shipped
    kicks: Kicks
    known_start: tuple[str, ...]


def conditions(jobs: Sequence[Job]) -> Conditions:
    """The conditions of the planned jobs."""
    from agents.experiments.scenarios import SoccerDriver
    from agents.policies.paths import EXP1_VERTICES
    from localizers.registry import spec

    worlds = {}
    for study in STUDIES:
        first = next((j for j in jobs if j.study == study), None)
        if first is not None:
            worlds[study] = first.world()
    cs, kalman, mcl = shipped("candidate_sets"), shipped("kalman"), shipped("mcl_bearing_paper")
    driver = SoccerDriver(0)
    return Conditions(
        worlds={study: world_facts(w) for study, w in worlds.items()},
        exp1=exp1_geometry(worlds["exp1"], EXP1_VERTICES) if "exp1" in worlds else None,
        shipped=Shipped(
            cs.max_sets,
            cs.prune_error_rad,
            cs.abort_error_rad,
            cs.determine_below,
            cs.max_live_candidates,
            kalman.vision_position_std_m,
            mcl.gate_rad,
        ),
        kicks=Kicks(
            math.degrees(driver.kick_out_spread_rad), driver.kick_out_speed_mps, driver.shot_speed_mps, driver.after_shot_s
        ),
        known_start=tuple(m.label for m in BASELINES if spec(m.localizer).needs_prior),
    )
