"""World configurations: frozen dataclasses loaded from ``configs/worlds/<name>.yaml``.

Every unit is in the field name (``_m``, ``_rad``, ``_s``, ``_mps``). Loading goes through
:func:`localizers.schema.from_mapping`, which rejects unknown keys and wrong types with
the key and the file in the message; ranges are checked in ``__post_init__``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import crowdloc_configs
from localizers.schema import ConfigError, check, from_mapping, load_yaml

CONFIG_DIR = crowdloc_configs.path()  # package data (configs/ in the checkout)
WORLD_DIR = CONFIG_DIR / "worlds"


@dataclass(frozen=True)
class LandmarkConfig:
    """A pole-like landmark seen by the bearing camera."""

    name: str
    x_m: float
    y_m: float
    radius_m: float = 0.05
    max_range_m: float = math.inf  # beyond this the camera cannot detect it (small poles)

    def __post_init__(self) -> None:
        check(self.radius_m > 0, f"landmark {self.name!r}: radius_m must be > 0, got {self.radius_m}")
        check(self.max_range_m > 0, f"landmark {self.name!r}: max_range_m must be > 0, got {self.max_range_m}")


@dataclass(frozen=True)
class RobotConfig:
    """Our differential-drive robot (a pymunk circle)."""

    radius_m: float = 0.25
    mass_kg: float = 30.0
    max_speed_mps: float = 1.75
    max_turn_rate_rps: float = 3.0
    friction: float = 0.5
    start_pose: tuple[float, float, float] | None = None  # fixed start; None: random in start_region_m
    start_region_m: tuple[float, float, float, float] | None = None  # (xmin, ymin, xmax, ymax)

    def __post_init__(self) -> None:
        check(self.radius_m > 0, f"robot.radius_m must be > 0, got {self.radius_m}")
        check(self.mass_kg > 0, f"robot.mass_kg must be > 0, got {self.mass_kg}")
        check(self.max_speed_mps > 0, f"robot.max_speed_mps must be > 0, got {self.max_speed_mps}")
        check(self.max_turn_rate_rps > 0, f"robot.max_turn_rate_rps must be > 0, got {self.max_turn_rate_rps}")
        check(
            self.start_pose is not None or self.start_region_m is not None,
            "robot: give start_pose or start_region_m",
        )


@dataclass(frozen=True)
class OdometryConfig:
    """Probabilistic Robotics odometry noise (variances per squared unit) and wheel slip."""

    alpha1: float = 0.01  # rad^2 / rad^2   rotation noise from rotation
    alpha2: float = 0.01  # rad^2 / m^2     rotation noise from translation
    alpha3: float = 0.01  # m^2 / m^2       translation noise from translation
    alpha4: float = 0.01  # m^2 / rad^2     translation noise from rotation
    slip_probability: float = 0.0  # per step: the wheels slip and the body moves less than reported
    slip_max_fraction: float = 0.5  # a slipping step loses U(0, this) of the commanded motion

    def __post_init__(self) -> None:
        for name in ("alpha1", "alpha2", "alpha3", "alpha4"):
            check(getattr(self, name) >= 0, f"odometry.{name} must be >= 0, got {getattr(self, name)}")
        check(0 <= self.slip_probability <= 1, f"odometry.slip_probability must be in [0, 1], got {self.slip_probability}")
        check(0 <= self.slip_max_fraction <= 1, f"odometry.slip_max_fraction must be in [0, 1], got {self.slip_max_fraction}")

    @property
    def alphas(self) -> tuple[float, float, float, float]:
        return (self.alpha1, self.alpha2, self.alpha3, self.alpha4)


@dataclass(frozen=True)
class BearingCameraConfig:
    """Camera reporting landmark bearings: omnidirectional (the papers' robots) or, with
    ``fov_rad`` below a full turn, a forward-looking one that must be turned toward landmarks."""

    noise_std_rad: float = math.radians(1.0)
    max_range_m: float = math.inf  # applies to every landmark on top of its own max_range_m
    fov_rad: float = 2 * math.pi  # horizontal field of view centred on the robot's heading
    dropout_probability: float = 0.0  # a visible landmark is missed in a frame
    false_detection_probability: float = 0.0  # per slot and frame: a wrong bearing is reported

    def __post_init__(self) -> None:
        check(self.noise_std_rad >= 0, f"camera.noise_std_rad must be >= 0, got {self.noise_std_rad}")
        check(self.max_range_m > 0, f"camera.max_range_m must be > 0, got {self.max_range_m}")
        check(0 < self.fov_rad <= 2 * math.pi, f"camera.fov_rad must be in (0, 2 pi], got {self.fov_rad}")
        check(0 <= self.dropout_probability <= 1, f"camera.dropout_probability must be in [0, 1], got {self.dropout_probability}")
        check(
            0 <= self.false_detection_probability <= 1,
            f"camera.false_detection_probability must be in [0, 1], got {self.false_detection_probability}",
        )


@dataclass(frozen=True)
class LidarConfig:
    """2-D scanning range finder (default: Hokuyo UTM-30LX)."""

    fov_rad: float = math.radians(270.0)
    beams: int = 1081
    max_range_m: float = 30.0
    range_std_m: float = 0.01

    def __post_init__(self) -> None:
        check(0 < self.fov_rad <= 2 * math.pi, f"lidar.fov_rad must be in (0, 2 pi], got {self.fov_rad}")
        check(self.beams >= 1, f"lidar.beams must be >= 1, got {self.beams}")
        check(self.max_range_m > 0, f"lidar.max_range_m must be > 0, got {self.max_range_m}")
        check(self.range_std_m >= 0, f"lidar.range_std_m must be >= 0, got {self.range_std_m}")

    @property
    def relative_angles_rad(self) -> tuple[float, float]:
        """First and last beam angle relative to the robot heading."""
        if self.beams == 1:
            return (0.0, 0.0)
        full_turn = math.isclose(self.fov_rad, 2 * math.pi)
        span = self.fov_rad * (self.beams - 1) / self.beams if full_turn else self.fov_rad
        return (-span / 2, span / 2)


@dataclass(frozen=True)
class SonarConfig:
    """A ring of sonar range sensors around the body: how near the walls and the crowd are.

    ``sensors`` transducers, evenly spaced from the heading counter-clockwise, each report
    the nearest wall or moving body inside its cone (``cone_rad`` wide, sampled by
    ``rays_per_cone`` rays), measured from the robot's centre; ``max_range_m`` when
    nothing is within range. None of the papers' worlds has one: it is the obstacle
    awareness a learned policy may use (add it with the env kwarg ``sonar={}``).
    """

    sensors: int = 12
    cone_rad: float = math.radians(30.0)
    rays_per_cone: int = 5
    max_range_m: float = 2.0
    range_std_m: float = 0.02

    def __post_init__(self) -> None:
        check(self.sensors >= 1, f"sonar.sensors must be >= 1, got {self.sensors}")
        spacing = 2 * math.pi / self.sensors
        check(
            0 < self.cone_rad <= spacing + 1e-12,
            f"sonar.cone_rad must be in (0, 2 pi / sensors = {spacing:.4f}] (cones may not overlap), got {self.cone_rad}",
        )
        check(self.rays_per_cone >= 1, f"sonar.rays_per_cone must be >= 1, got {self.rays_per_cone}")
        check(self.max_range_m > 0, f"sonar.max_range_m must be > 0, got {self.max_range_m}")
        check(self.range_std_m >= 0, f"sonar.range_std_m must be >= 0, got {self.range_std_m}")


@dataclass(frozen=True)
class SoccerCrowdConfig:
    """Other soccer robots and a ball (candidate-set paper, Exp 2)."""

    ball: bool = True
    ball_radius_m: float = 0.11
    ball_mass_kg: float = 0.45
    ball_decay_per_s: float = 0.6  # fraction of ball speed lost per second (rolling friction)
    ball_occludes: bool = False  # the omni camera sits above ball height
    goalkeeper: bool = True  # the first robot keeps the goal between keeper_posts
    keeper_posts: tuple[tuple[float, float], tuple[float, float]] | None = None
    keeper_offset_m: float = 0.4  # distance in front of the goal line
    chaser_fraction: float = 0.5  # share of the remaining robots that go for the ball
    kick_speed_mps: float = 3.0  # ball speed after a chaser kicks it
    wander_dwell_s: float = 3.0  # wanderers pick a new target after at most this long

    def __post_init__(self) -> None:
        check(0 <= self.chaser_fraction <= 1, f"soccer.chaser_fraction must be in [0, 1], got {self.chaser_fraction}")
        check(self.ball_radius_m > 0, f"soccer.ball_radius_m must be > 0, got {self.ball_radius_m}")
        check(0 <= self.ball_decay_per_s < 1, f"soccer.ball_decay_per_s must be in [0, 1), got {self.ball_decay_per_s}")


@dataclass(frozen=True)
class QueueCrowdConfig:
    """People queueing along two opposite walls (LIDAR paper's room)."""

    left_x_m: float = 0.6  # x of the left queue's line
    right_x_m: float = 6.4  # x of the right queue's line
    head_y_m: float = 6.2  # y of the queue heads (queues extend toward smaller y)
    spacing_m: float = 0.6  # distance between people in a queue
    step_period_s: float = 5.0  # every person steps forward this often
    walk_speed_mps: float = 1.0  # speed of a head walking over to the other queue

    def __post_init__(self) -> None:
        check(self.spacing_m > 0, f"queues.spacing_m must be > 0, got {self.spacing_m}")
        check(self.step_period_s > 0, f"queues.step_period_s must be > 0, got {self.step_period_s}")
        check(self.walk_speed_mps > 0, f"queues.walk_speed_mps must be > 0, got {self.walk_speed_mps}")


@dataclass(frozen=True)
class WalkerConfig:
    """Free-walking pedestrians with social-force avoidance (Helbing and Molnar style)."""

    count: int = 0
    desired_speed_mps: float = 1.0
    relaxation_s: float = 0.5  # time to reach the desired velocity
    repulsion_strength_mps2: float = 2.0  # magnitude of the exponential repulsion
    repulsion_range_m: float = 0.3  # length scale of the repulsion

    def __post_init__(self) -> None:
        check(self.count >= 0, f"walkers.count must be >= 0, got {self.count}")
        check(self.desired_speed_mps > 0, f"walkers.desired_speed_mps must be > 0, got {self.desired_speed_mps}")
        check(self.relaxation_s > 0, f"walkers.relaxation_s must be > 0, got {self.relaxation_s}")
        check(self.repulsion_range_m > 0, f"walkers.repulsion_range_m must be > 0, got {self.repulsion_range_m}")


@dataclass(frozen=True)
class CrowdConfig:
    """Moving obstacles. ``count`` is the crowd density: the number of robots or queueing people."""

    kind: Literal["soccer", "queues"] = "soccer"
    count: int = 0
    max_count: int = 14
    radius_m: float = 0.25
    mass_kg: float = 30.0
    speed_mps: float = 1.75
    soccer: SoccerCrowdConfig = field(default_factory=SoccerCrowdConfig)
    queues: QueueCrowdConfig = field(default_factory=QueueCrowdConfig)
    walkers: WalkerConfig = field(default_factory=WalkerConfig)

    def __post_init__(self) -> None:
        check(self.max_count >= 0, f"crowd.max_count must be >= 0, got {self.max_count}")
        check(
            0 <= self.count <= self.max_count,
            f"crowd.count must be in [0, {self.max_count}], got {self.count}",
        )
        check(self.radius_m > 0, f"crowd.radius_m must be > 0, got {self.radius_m}")
        check(self.mass_kg > 0, f"crowd.mass_kg must be > 0, got {self.mass_kg}")
        check(self.speed_mps > 0, f"crowd.speed_mps must be > 0, got {self.speed_mps}")


@dataclass(frozen=True)
class WorldConfig:
    """One scenario: geometry, landmarks, crowd, robot, sensors and noise."""

    name: str
    description: str
    size_m: tuple[float, float]  # the field / room the robot moves in, from (0, 0)
    dt_s: float
    max_episode_steps: int
    robot: RobotConfig
    walls: tuple[tuple[float, float, float, float], ...] = ()  # extra segments (x1, y1, x2, y2)
    boundary_margin_m: float = 0.0  # boundary walls this far outside the field
    landmarks: tuple[LandmarkConfig, ...] = ()
    odometry: OdometryConfig = field(default_factory=OdometryConfig)
    camera: BearingCameraConfig | None = None
    lidar: LidarConfig | None = None
    sonar: SonarConfig | None = None
    crowd: CrowdConfig = field(default_factory=CrowdConfig)

    def __post_init__(self) -> None:
        w, h = self.size_m
        check(w > 0 and h > 0, f"world {self.name!r}: size_m must be positive, got {self.size_m}")
        check(self.dt_s > 0, f"world {self.name!r}: dt_s must be > 0, got {self.dt_s}")
        check(self.max_episode_steps >= 1, f"world {self.name!r}: max_episode_steps must be >= 1, got {self.max_episode_steps}")
        check(self.boundary_margin_m >= 0, f"world {self.name!r}: boundary_margin_m must be >= 0, got {self.boundary_margin_m}")
        check(self.camera is not None or self.lidar is not None, f"world {self.name!r}: needs a camera or a lidar")
        check(self.camera is None or len(self.landmarks) > 0, f"world {self.name!r}: a camera needs landmarks")
        names = [lm.name for lm in self.landmarks]
        check(len(set(names)) == len(names), f"world {self.name!r}: landmark names repeat: {names}")

    @property
    def arena_m(self) -> tuple[float, float, float, float]:
        """``(xmin, ymin, xmax, ymax)`` inside the boundary walls."""
        m = self.boundary_margin_m
        return (-m, -m, self.size_m[0] + m, self.size_m[1] + m)


def world_path(name: str) -> Path:
    """Path of a shipped world config."""
    return WORLD_DIR / f"{name}.yaml"


def available_worlds() -> list[str]:
    return sorted(p.stem for p in WORLD_DIR.glob("*.yaml"))


def load_world(name_or_path: str | Path) -> WorldConfig:
    """Load a world by shipped name (``"robocup_crowded"``) or by YAML path.

    Raises:
        ConfigError: naming the unknown world, or the bad key and the file.
    """
    path = Path(name_or_path)
    if path.suffix not in (".yaml", ".yml"):
        path = world_path(str(name_or_path))
        if not path.is_file():
            raise ConfigError(f"unknown world {str(name_or_path)!r}; shipped worlds: {', '.join(available_worlds())}")
    return from_mapping(WorldConfig, load_yaml(path), where=str(path))
