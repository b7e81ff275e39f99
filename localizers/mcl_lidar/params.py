"""``mcl_lidar``'s parameters (:class:`LidarMCLParams`) and their choice in a world too large for the beam model.

The parameters are checked when made (one :class:`~core.schema.ConfigError` per rule);
the filter that uses them is :mod:`localizers.mcl_lidar`, the measurement models
:mod:`localizers.mcl_lidar.beam_model` (both import this module, it imports neither).

Map size (measured on a synthetic 150 m x 100 m campus of 1,000 walls, one core): the
likelihood field is the only map model a ``likelihood_field`` filter builds (the ray-cast
table is built by :meth:`~localizers.mcl_lidar.LidarMCL.beam_model` alone, for ``model: beam``); at 5 cm it is
6.2 M cells, 8 bytes each for the distances and 4 for the log field of each maximum range
(75 MB), built in about 0.4 s plus 0.4 s for the log field. The beam model's table of the
same grid at 720 directions would be 17 GB: the beam model is for rooms. Every table's memory
is estimated before it is built and one above ``max_table_mb`` refused (a beam model whose
table would be, when the filter is made); in such a world the env wrapper gives ``mcl_lidar``
:data:`LARGE_MAP_PARAMS`, the campus reference's likelihood field at 0.1 m (:func:`large_map_params`;
``crowdloc eval --env-id crowdloc/StereoCampus-v0 --localizers mcl_lidar``: peak RSS about
0.5 GB, errors of 6 cm, a pose on every step over 300 steps of ``route_follower``). What does not
scale: ``recovery_candidates`` (and the particles of a reset without a prior) are uniform
over the map bounds, so their density falls with the area: 20,000 candidates put about 4
within 0.25 m and 10 deg of the true pose in the 7 m x 7 m room, and 0.015 on the campus,
where injection therefore almost never recovers a lost filter; the weighing costs the
same (about 20 ms).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Literal

from core.schema import check, check_at_most, check_ranges, is_int
from localizers.base import DEFAULT_MAX_SPREAD_M, check_max_spread
from localizers.particles import MAX_PARTICLES, PARTICLE_MEMORY
from localizers.range_table import MAX_TABLE_MB, RANGE_TABLE_ENTRY_BYTES, range_table_shape, table_megabytes

__all__ = ["LARGE_MAP_PARAMS", "MAX_TABLE_DIRECTIONS", "LidarMCLParams", "large_map_mcl", "large_map_params"]

_log = logging.getLogger("localizers.mcl_lidar")  # the localizer's logger, whose choice it logs
#: the large-map choices already logged in this process (a benchmark makes an env per episode: the
#: warning is said once, then at debug level)
_told: set[tuple[Any, ...]] = set()


#: mcl_lidar's parameters where the beam model's ray-cast table of the world's map would exceed
#: ``max_table_mb`` (a campus) and the user did not choose ``model``: ROS amcl's likelihood-field
#: configuration at 0.1 m, as the campus's LIDAR reference runs it (:mod:`agents.experiments.scene_maps`; no recovery or
#: lost test: injection drawn over a campus almost never lands near the robot, and the lost test fires
#: when people pass). With the beam model's defaults on the likelihood field, the campus filter spreads
#: along the sidewalk and claims a pose on 7 % of the steps (measured, 300 steps of route_follower)
LARGE_MAP_PARAMS: dict[str, Any] = {
    "model": "likelihood_field",
    "table_resolution_m": 0.1,
    "beam_stride": 8,
    "sampling": 1.0,
    "recovery": False,
    "lost_ratio": 0.0,
}

#: the most directions per cell of the ray-cast table (0.1 deg)
MAX_TABLE_DIRECTIONS = 3600


@dataclass(frozen=True)
class LidarMCLParams:
    """LIDAR MCL parameters (defaults: ``configs/localizers/mcl_lidar.yaml``).

    Attributes:
        n_particles: set size (paper B: 1000); the initial size when KLD-sampling is on.
        sampling: the paper's "sampling parameter" (swept 0.1..1.0): the motion model uses
            ``alphas = sampling * alphas_base``.
        alphas_base: alpha1..alpha4 of the odometry motion model at ``sampling = 1``
            (Probabilistic Robotics Table 5.6; alpha1 rad^2/rad^2, alpha2 rad^2/m^2,
            alpha3 m^2/m^2, alpha4 m^2/rad^2).
        min_translation_std_m, min_rotation_std_rad: per-update motion-noise floors.
        update_min_travel_m, update_min_rotation_rad: an update is done once the robot has
            travelled or turned this much since the last one (0: at every scan).
        model: ``"beam"`` (Table 6.1, the paper's) or ``"likelihood_field"`` (Table 6.3).
        hit_std_m: sd of the hit Gaussian (the paper's "hit", swept 0.1..1.0).
        lambda_short: rate of the exponential of unexpected short readings, 1/m.
        z_hit, z_short, z_max, z_rand: mixture weights (sum to 1; the likelihood field uses
            z_hit and z_rand and skips max-range beams).
        beam_stride: use every ``beam_stride``-th beam (1: all).
        table_resolution_m: cell size of the ray-cast table and of the likelihood field.
        table_directions: directions per cell of the ray-cast table (720: 0.5 deg).
        max_table_mb: the most memory (MB, per process) one map table may take: the ray-cast
            table (4 bytes per cell and direction) or the likelihood field (about 12 bytes a
            cell). A table above it is refused with a :class:`~core.schema.ConfigError`
            when the filter is made (the beam model's) or its field built, giving the estimate
            and what to change. The beam model's table of a 150 m x 100 m campus at 5 cm and 720
            directions would be 17 GB: in such a world the env wrapper picks
            :data:`LARGE_MAP_PARAMS` unless ``model`` is given (:func:`large_map_params`).
        resample_ess_fraction: resample when the effective sample size falls below this
            fraction of the set (1.0: after every update, as Table 8.2).
        kld: adapt the set size by KLD-sampling (Fox 2003).
        kld_epsilon, kld_delta: bound on the KL divergence and its confidence ``1 - delta``.
        kld_bin_xy_m, kld_bin_theta_rad: histogram bin size of KLD-sampling.
        min_particles, max_particles: limits of the KLD set size.
        recovery: augmented MCL, random particles when the short-term likelihood average
            drops below the long-term one (Table 8.3), drawn from the scan (see
            ``recovery_candidates``). On by default (ours); off is the paper's plain
            MCL, as its reproduction runs it.
        alpha_slow, alpha_fast: rates of the long- and short-term averages (kept with or
            without ``recovery``: they also tell when the filter is lost).
        lost_ratio: lost detection (ours): no pose is claimed while the short-term average of
            the per-beam likelihood is below ``lost_ratio`` times the long-term one (0: never).
        recovery_candidates: the injected particles are drawn, in proportion to their
            likelihood, from this many poses uniform over the map bounds, weighed by the scan
            (every ``recovery_beam_stride``-th beam) through the same measurement model (ours,
            sensor-resetting after Lenser and Veloso 2000; uniform particles alone almost
            never land near the pose in a room, so the book's injection does not recover).
            Only done when particles are injected.
        recovery_beam_stride: the beam stride of that weighing.
        global_candidates: global localization (a start without a prior): at the first update
            the particle set is drawn from this many poses uniform over the map bounds, in
            proportion to their likelihood under the scan (every ``recovery_beam_stride``-th
            beam), and weighed by the rest of the scan; 0 (the default): the uniform particles
            are weighed as they are. A thousand uniform particles leave about two within 0.5 m
            and 20 deg of the pose in a 7 m room, so a pose turned 90 or 180 deg about the
            room's centre often wins the first scan (ours, as ``recovery_candidates``).
        max_spread_m: no pose is claimed while the position spread exceeds this (ours).
        min_range_m, min_informative_fraction: a scan in which fewer than this fraction of the
            (strided) beams read a range in ``(min_range_m, max_range)`` carries no information
            on the pose (a blank or blocked scan: all at the maximum range, all zero): it is not
            weighed, and the particles only move by the odometry (ours).
        initial_position_std_m, initial_heading_std_rad: spread around a prior without a
            finite covariance.
        parallel: evaluate the particles on numba's thread pool. Off by default: on a
            shared 2-core machine, or with several envs in parallel processes, waking the
            pool costs more than it saves; on a quiet multi-core machine it divides the
            update time by about the number of cores. Do not use it with filters running in
            several threads of one process (numba's default threading layer is not
            thread-safe). Not bit-reproducible against the serial kernel: freshly compiled,
            the parallel kernel gives the serial results exactly, but loaded from numba's disk
            cache its beam-model log-likelihoods differ by up to ~1e-9 relative (measured:
            5.2e-6 absolute on sums of ~-4000 over 1081 beams, 1000 particles; likelihood
            field 1.8e-12), with or without ``fastmath`` on the parallel variant (each particle
            is summed by one thread, in beam order, so it is not a thread-order reduction).
            Calls of one compiled kernel are deterministic; the pinned numbers use the serial one.
        deskew: undo the motion of the robot during a swept scan before weighing it (ours; off in
            the papers' reproductions, whose scans are taken as they come): each beam is moved to the
            pose at the scan's end by the step's odometry increment, a constant velocity across the step
            assumed (:func:`core.geometry.deskewed_scan`), using the beam times the scan carries
            (:attr:`localizers.base.ScanMeasurement.beam_lags_s`, from a LIDAR's ``sweep_s``); a scan
            without them is used as it is.
    """

    n_particles: int = 1000
    sampling: float = 0.1
    alphas_base: tuple[float, float, float, float] = (0.2, 0.2, 0.2, 0.2)
    min_translation_std_m: float = 0.005
    min_rotation_std_rad: float = 0.005
    update_min_travel_m: float = 0.5
    update_min_rotation_rad: float = math.pi / 6.0
    model: Literal["beam", "likelihood_field"] = "beam"
    hit_std_m: float = 0.2
    lambda_short: float = 0.1
    z_hit: float = 0.8
    z_short: float = 0.1
    z_max: float = 0.05
    z_rand: float = 0.05
    beam_stride: int = 1
    table_resolution_m: float = 0.05
    table_directions: int = 720
    max_table_mb: float = MAX_TABLE_MB
    resample_ess_fraction: float = 1.0
    kld: bool = False
    kld_epsilon: float = 0.05
    kld_delta: float = 0.01
    kld_bin_xy_m: float = 0.5
    kld_bin_theta_rad: float = math.radians(10.0)
    min_particles: int = 100
    max_particles: int = 5000
    recovery: bool = True
    alpha_slow: float = 0.001
    alpha_fast: float = 0.1
    initial_position_std_m: float = 0.1
    initial_heading_std_rad: float = 0.1
    parallel: bool = False
    lost_ratio: float = 0.9
    recovery_candidates: int = 20_000
    recovery_beam_stride: int = 8
    global_candidates: int = 0
    max_spread_m: float = DEFAULT_MAX_SPREAD_M
    min_range_m: float = 0.1
    min_informative_fraction: float = 0.1
    deskew: bool = False

    def __post_init__(self) -> None:
        name = "LidarMCLParams"
        check(self.n_particles >= 2, f"{name}.n_particles must be >= 2, got {self.n_particles!r}")
        check(
            len(self.alphas_base) == 4 and all(math.isfinite(a) and a >= 0.0 for a in self.alphas_base),
            f"{name}.alphas_base must be four finite values >= 0, got {self.alphas_base!r}",
        )
        check_ranges(
            self,
            name,
            positive=(
                "sampling",
                "hit_std_m",
                "lambda_short",
                "table_resolution_m",
                "max_table_mb",
                "kld_epsilon",
                "kld_bin_xy_m",
                "kld_bin_theta_rad",
            ),
            non_negative=(
                "min_translation_std_m",
                "min_rotation_std_rad",
                "update_min_travel_m",
                "update_min_rotation_rad",
                "z_hit",
                "z_short",
                "z_max",
                "z_rand",
                "min_range_m",
                "initial_position_std_m",
                "initial_heading_std_rad",
            ),
        )
        total = self.z_hit + self.z_short + self.z_max + self.z_rand
        check(
            abs(total - 1.0) <= 1e-6,
            f"{name}: z_hit + z_short + z_max + z_rand must be 1 (Probabilistic Robotics Table 6.1), got {total!r}",
        )
        check_at_most(
            self,
            name,
            dict.fromkeys(
                ("n_particles", "min_particles", "max_particles", "recovery_candidates", "global_candidates"), MAX_PARTICLES
            ),
            PARTICLE_MEMORY,
        )
        check(self.beam_stride >= 1, f"{name}.beam_stride must be >= 1, got {self.beam_stride!r}")
        check(self.table_directions >= 8, f"{name}.table_directions must be >= 8, got {self.table_directions!r}")
        check_at_most(
            self,
            name,
            {"table_directions": MAX_TABLE_DIRECTIONS},
            "0.1 deg, finer than a LIDAR's beam step (the UTM-30LX's is 0.25 deg), and memory: the ray-cast table holds a "
            "range per cell and direction",
        )
        check(
            0.0 < self.resample_ess_fraction <= 1.0,
            f"{name}.resample_ess_fraction must be in (0, 1], got {self.resample_ess_fraction!r}",
        )
        check(0.0 < self.kld_delta < 1.0, f"{name}.kld_delta must be in (0, 1), got {self.kld_delta!r}")
        check(
            2 <= self.min_particles <= self.max_particles,
            f"{name} needs 2 <= min_particles <= max_particles, got {self.min_particles!r}, {self.max_particles!r}",
        )
        check(
            0.0 < self.alpha_slow < self.alpha_fast <= 1.0,
            f"{name} needs 0 < alpha_slow < alpha_fast <= 1, got {self.alpha_slow!r}, {self.alpha_fast!r}",
        )
        check(0.0 <= self.lost_ratio <= 1.0, f"{name}.lost_ratio must be in [0, 1] (0: never lost), got {self.lost_ratio!r}")
        check(self.recovery_candidates >= 1, f"{name}.recovery_candidates must be >= 1, got {self.recovery_candidates!r}")
        check(is_int(self.global_candidates) and self.global_candidates >= 0,
              f"{name}.global_candidates must be an integer >= 0 (0: off), got {self.global_candidates!r}")  # fmt: skip
        check(self.recovery_beam_stride >= 1, f"{name}.recovery_beam_stride must be >= 1, got {self.recovery_beam_stride!r}")
        check_max_spread(name, self.max_spread_m)
        check(
            0.0 <= self.min_informative_fraction <= 1.0,
            f"{name}.min_informative_fraction must be in [0, 1], got {self.min_informative_fraction!r}",
        )

    @property
    def alphas(self) -> tuple[float, float, float, float]:
        """The effective alpha1..alpha4: ``sampling * alphas_base``."""
        a1, a2, a3, a4 = (self.sampling * a for a in self.alphas_base)
        return (a1, a2, a3, a4)


def large_map_params(env: Any, sensor: str, params: Mapping[str, Any] | None) -> Mapping[str, Any] | None:
    """``mcl_lidar``'s preparation (its registry entry names it): in a world whose map would give
    the beam model a ray-cast table above ``max_table_mb`` (``env.landmark_map`` cut at the
    sensor's height), :data:`LARGE_MAP_PARAMS` under the user's ``params``, logged; otherwise, or
    when ``params`` names a ``model``, ``params`` unchanged (an explicit beam model is then
    refused when the filter is made, with the table's estimate)."""
    from localizers.registry import load_params

    if params is not None and not isinstance(params, Mapping):
        return params  # refused by name when the parameters are loaded
    return large_map_mcl(env, sensor, params, load_params("mcl_lidar", params), "mcl_lidar")


def large_map_mcl(
    env: Any, sensor: str, params: Mapping[str, Any] | None, resolved: LidarMCLParams, who: str
) -> Mapping[str, Any] | None:
    """The LIDAR MCL parameters ``params`` (which resolve to ``resolved``) for the world of ``env``:
    :data:`LARGE_MAP_PARAMS` under ``params`` where the beam model's table would exceed
    ``max_table_mb`` and ``params`` names no ``model``, logged as ``who``'s choice; else ``params``
    itself (the same object). Shared by ``mcl_lidar`` and ``far_point_mcl`` (its ``mcl`` section).

    Raises:
        ConfigError: if a beam stride is not below the sensor's beam count (a scan would be
            weighed by its first beam alone).
    """
    from localizers.measurements import sensor_map

    beams = len(env.sensor_metadata[sensor].get("beam_angles_rad", ()))
    for name in ("beam_stride", "recovery_beam_stride"):
        stride = getattr(resolved, name)
        check(beams <= 1 or stride < beams,
              f"{who}.{name} {stride} is not below the {beams} beams of sensor {sensor!r}: every scan would be "
              f"weighed by its first beam alone; use fewer than {beams}")  # fmt: skip
    if "model" in (params or {}) or resolved.model != "beam":
        return params
    bounds = sensor_map(env.landmark_map, env.sensor_metadata[sensor]).bounds_m
    shape = range_table_shape(bounds, resolved.table_resolution_m, resolved.table_directions)
    megabytes = table_megabytes(shape, RANGE_TABLE_ENTRY_BYTES)
    if megabytes <= resolved.max_table_mb:
        return params
    chosen = {**LARGE_MAP_PARAMS, **(params or {})}
    said = (who, shape, tuple(sorted(chosen.items())))
    level = logging.DEBUG if said in _told else logging.WARNING
    _told.add(said)
    _log.log(
        level,
        "%s: the beam model's ray-cast table of this %g m x %g m map would be %d x %d cells x %d directions "
        "(%.0f MB, above max_table_mb %g): using %s (the campus reference's likelihood field; give localizer_params "
        "model=... to choose)",
        who, bounds[2] - bounds[0], bounds[3] - bounds[1], *shape, megabytes, resolved.max_table_mb,
        ", ".join(f"{k} {v}" for k, v in chosen.items() if k in LARGE_MAP_PARAMS),
    )  # fmt: skip
    return chosen
