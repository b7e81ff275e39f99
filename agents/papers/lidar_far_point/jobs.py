"""The runs: record each episode once, one real ``far_point_mcl`` pass and one reference pass over it, then the MCL replays.

How the sweep stays affordable: each (seed, crowd size) episode is recorded once (the world
does not depend on the localizer), with both LIDARs: the room's at 0.2 m, under test, and the
reference LIDAR above the crowd (``experiment.REFERENCE_SENSOR``). The MCL weighs a scan only
every 0.5 m of travel and the far-point filter uses odometry only, so neither the update steps
nor the far-point scans depend on the MCL's parameters. One real ``far_point_mcl`` pass per
episode (:func:`run_episode`) therefore yields the far-point scan of every update step; every
configuration is then ``mcl_lidar`` fed the raw or the far-point scans at those steps
(:func:`run_chunk`). Each replay checks that it weighed exactly those steps, and the pass's
own estimates must equal the replay of the same configuration bit for bit
(:func:`pass_identity`), so the result is ``far_point_mcl``'s.

The reference pose (the paper's yardstick): one ``mcl_lidar`` pass per episode on the
reference LIDAR's scans, with its own generator, on the same update schedule (it must weigh
the same steps); each configuration's error is measured against it and against the true pose.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from agents.common.sweep import run_tasks
from agents.evaluate import consistency, metrics
from agents.experiments.replay import Recording, feed, odometry_deltas, record, replay_into, start_prior
from core.geometry import between
from core.raycast import cast_rays
from localizers.base import LandmarkMap, ScanMeasurement
from localizers.mcl_lidar import LidarMCL, LidarMCLParams
from localizers.registry import make_localizer
from localizers.scan_filter import FarPointMCL, far_points, window_covariance

from . import world
from .experiment import (
    CROWD_SIZE,
    DENSITY_PARAMS,
    ENV_ID,
    REFERENCE_LOCALIZER,
    REFERENCE_RNG_SALT,
    REFERENCE_SENSOR,
    RNG_SALT,
    WALL_TOL_M,
    Config,
    Plan,
    both,
    driver_factory,
    env_kwargs,
    episode_steps,
    pass_config,
    reference_mcl_params,
    start_pose,
)

Array = NDArray[np.float64]
Breakdown = tuple[int, int, int, int]

# ------------------------------------------------------------------------------------ stage 1: episodes


@dataclass(frozen=True)
class EpisodeTask:
    """Record one episode and run the far-point pass over it."""

    seed: int
    crowd_size: int
    laps: int
    snapshot: bool = False


@dataclass(frozen=True)
class Snapshot:
    """Fig. 5: the scans at one update step, in the world frame (placed by the true pose)."""

    step: int
    pose: Array
    raw_xy: Array
    accumulated_xy: Array
    far_xy: Array
    people_xy: Array
    people_radius_m: float
    beams: dict[str, Breakdown]


@dataclass(frozen=True)
class Episode:
    """One recorded episode, reduced to what the MCL replays need.

    Attributes:
        task: what was run.
        recording: the :class:`agents.experiments.replay.Recording` without its LIDAR leaves (both LIDARs').
        scan_map: the map the LIDAR under test's localizers get (cut at its height).
        update_steps: ``(K,)`` steps at which the MCL weighs a scan.
        raw_scans: ``(K, B)`` the LIDAR's scans at those steps.
        far_scans: ``(K, B)`` the far-point scans handed to the MCL at those steps.
        angles_rad, max_range_m: the scan format.
        pass_estimates: ``(K, 3)`` the real ``far_point_mcl`` pass (``PASS_PARAMS``).
        reference_estimates: ``(K, 3)`` the reference pose: ``mcl_lidar`` on the reference
            LIDAR's scans (``REFERENCE_MCL_PARAMS``, its map cut at that LIDAR's height).
        reference_nees: ``(K,)`` the reference pass's 3-dof pose NEES against the true pose.
        beams: ``"raw"`` / ``"far"`` -> ``(K, 4)`` beams matching the empty room, short of
            it, past it, at maximum range (:func:`agents.evaluate.metrics.beam_breakdown`).
        wall_bias_m: ``"raw"`` / ``"far"`` -> ``(K,)`` mean of ``z - z*`` over the beams on
            the wall (the far point of a bin is the largest of many noisy returns).
        accumulated_points: ``(K,)`` points in the filter's window at each update.
        window_increments: ``(K, 3)`` the filter's window at each update
            (:attr:`localizers.scan_filter.ScanFilter.window_increment`).
        window_fixed: ``(K,)`` whether the update was a fix on the window's points (not on a
            blank scan): the replays add the window's odometry noise of the last such fix to a
            far-point configuration's covariance, as ``far_point_mcl`` does
            (:func:`window_terms`).
        contacts: contacts of our robot in the episode.
        push_m: path length of our robot's motion that its commands do not explain.
        snapshot: Fig. 5 material (one episode only).
        record_s, pass_s: seconds spent recording and in the far-point pass.
        reference_s: seconds of the reference pass.
        cpu_s: CPU seconds of the whole task.
    """

    task: EpisodeTask
    recording: Recording
    scan_map: LandmarkMap
    update_steps: NDArray[np.int64]
    raw_scans: NDArray[np.float32]
    far_scans: Array
    angles_rad: Array
    max_range_m: float
    pass_estimates: Array
    reference_estimates: Array
    reference_nees: Array
    beams: dict[str, NDArray[np.int64]]
    wall_bias_m: dict[str, Array]
    accumulated_points: NDArray[np.int64]
    window_increments: Array
    window_fixed: NDArray[np.bool_]
    contacts: int
    push_m: float
    snapshot: Snapshot | None = None
    record_s: float = 0.0
    pass_s: float = 0.0
    reference_s: float = 0.0
    cpu_s: float = 0.0


class _CrowdTap:
    """Wraps the driver and keeps the crowd's positions at every observation it acts on (Fig. 5)."""

    def __init__(self, make_inner: Callable[[Any], Any]) -> None:
        self._make = make_inner
        self.inner: Any = None
        self.positions: list[Array] = []

    def reset(self, env: Any) -> None:
        self.inner = self._make(env)
        self.inner.reset(env)
        self.positions = []

    def act(self, env: Any) -> NDArray[np.float32]:
        self.positions.append(world.crowd_positions(env))
        action: NDArray[np.float32] = self.inner.act(env)
        return action

    @property
    def done(self) -> bool:
        return self.inner is not None and self.inner.done


def record_episode(seed: int, crowd_size: int, laps: int) -> tuple[Recording, list[Array]]:
    """The recording of ``laps`` laps of the square, and the crowd's positions at each step.

    Raises:
        RuntimeError: when the path did not finish within its steps (plus a margin).
    """
    steps = episode_steps(laps) + 10
    tap = _CrowdTap(driver_factory(laps))
    options = {"robot_pose": list(start_pose())}
    rec = record(ENV_ID, tap, seed, max_steps=steps, env_kwargs=env_kwargs(crowd_size, steps), reset_options=options)
    if not tap.done:
        raise RuntimeError(f"episode seed {seed}: the square path did not finish in {steps} steps")
    return rec, tap.positions


def unexplained_motion_m(recording: Recording) -> float:
    """Path length of the true motion beyond the commanded one (pushes), summed over the steps."""
    truth = recording.true_pose
    if truth.shape[0] < 2:
        return 0.0
    d = between(truth[:-1], truth[1:]) - recording.commanded
    return float(np.hypot(d[:, 0], d[:, 1]).sum())


def _world_xy(pose: Array, ranges_m: Array, angles_rad: Array) -> Array:
    """``(n, 2)`` end points of the beams ``ranges_m`` (robot-frame ``angles_rad``) from ``pose``."""
    a = angles_rad + pose[2]
    return np.stack([pose[0] + ranges_m * np.cos(a), pose[1] + ranges_m * np.sin(a)], axis=1)


class _UpdateLog:
    """The far-point pass's observer: at each update step, the scans and how they compare with the empty room.

    The empty room's range of a beam is cast from the true pose against the room's static
    segments where they stand (the walls, the door, the furniture the LIDAR's plane cuts:
    :func:`.world.true_walls_at` its height), not against the localizers' map, which has the
    table elsewhere (``map_offset_m``) and would call the beams on its legs short or past.
    """

    def __init__(self, rec: Recording, crowd_xy: Sequence[Array], snapshot: bool) -> None:
        name = world.lidar_name()
        meta = rec.sensors.get(name)
        if meta is None or meta.get("type") != "lidar":
            raise ValueError(f"the recording has no LIDAR {name!r}")
        self.lidar: NDArray[np.float32] = rec.observations[meta["key"]]
        self.angles = np.asarray(meta["beam_angles_rad"], dtype=np.float64)
        self.max_range = float(meta["max_range_m"])
        self.truth = rec.true_pose
        walls = world.true_walls_at(float(meta["height_m"]))  # what the LIDAR's plane cuts of the room
        self._segments = (np.ascontiguousarray(walls[:, :2]), np.ascontiguousarray(walls[:, 2:]), np.zeros((0, 2)), np.zeros(0))
        self._crowd_xy = crowd_xy
        self._want_snapshot = snapshot
        self._radius = world.people_radius_m()
        self.steps: list[int] = []
        self.far: list[Array] = []
        self.beams: dict[str, list[Breakdown]] = {"raw": [], "far": []}
        self.bias: dict[str, list[float]] = {"raw": [], "far": []}
        self.points: list[int] = []
        self.windows: list[Array] = []
        self.fixed: list[bool] = []
        self._fixes = 0
        self.snapshot: Snapshot | None = None
        self._most_short = -1

    def observe(self, t: int, localizer: Any, weighed: bool) -> None:
        if not weighed:
            return
        scan = localizer.processed_scan
        self.steps.append(t)
        self.far.append(np.array(scan.ranges_m))
        pose = self.truth[t]
        empty = cast_rays(pose[:2], self.angles + pose[2], self.max_range, *self._segments)
        raw_b = metrics.beam_breakdown(self.lidar[t], empty, self.max_range, tol_m=WALL_TOL_M)
        self.beams["raw"].append(raw_b)
        self.beams["far"].append(metrics.beam_breakdown(scan.ranges_m, empty, self.max_range, tol_m=WALL_TOL_M))
        for name, z in (("raw", self.lidar[t].astype(np.float64)), ("far", scan.ranges_m)):
            on_wall = np.abs(z - empty) < WALL_TOL_M
            self.bias[name].append(float(np.mean(z[on_wall] - empty[on_wall])) if on_wall.any() else float("nan"))
        self.points.append(int(localizer.filter.points_xy.shape[0]))
        self.windows.append(localizer.filter.window_increment)
        self.fixed.append(localizer.window_fixes > self._fixes)
        self._fixes = localizer.window_fixes
        if self._want_snapshot and raw_b[1] > self._most_short and t < len(self._crowd_xy):
            self._most_short = raw_b[1]
            self.snapshot = self._snapshot(t, localizer.filter, raw_b)

    def _snapshot(self, t: int, filt: Any, raw_b: Breakdown) -> Snapshot:
        """Fig. 5 at step ``t``: the raw scan, the filter's window and its far points, the crowd."""
        pose = self.truth[t]
        r = self.lidar[t].astype(np.float64)
        hit = r < self.max_range
        return Snapshot(
            t, pose.copy(), _world_xy(pose, r[hit], self.angles[hit]), filt.to_world(filt.points_xy, pose),
            filt.to_world(filt.far_points_xy, pose), self._crowd_xy[t].copy(), self._radius,
            {"raw": raw_b, "far": self.beams["far"][-1]},
        )  # fmt: skip


def episode_rng(seed: int, crowd_size: int) -> np.random.Generator:
    """The localizers' generator of an episode (the same for every configuration)."""
    return np.random.default_rng([seed, crowd_size, RNG_SALT])


def reference_rng(seed: int, crowd_size: int) -> np.random.Generator:
    """The reference MCL's generator of an episode (its own, not the configurations')."""
    return np.random.default_rng([seed, crowd_size, REFERENCE_RNG_SALT])


def reference_pass(rec: Recording, seed: int, crowd_size: int) -> tuple[Array, NDArray[np.int64], Array]:
    """The reference pose: ``mcl_lidar`` on the reference LIDAR's scans from the known start pose.

    Returns:
        ``(T, 3)`` its estimates (NaN between its updates), the ``(K,)`` steps it weighed and
        the ``(T,)`` NEES of its estimates against the true pose.
    """
    loc = make_localizer(REFERENCE_LOCALIZER, rec.localizer_map("scan", REFERENCE_SENSOR), dt_s=rec.dt_s,
                         params=reference_mcl_params())  # fmt: skip
    if not isinstance(loc, LidarMCL):
        raise TypeError(f"mcl_lidar built a {type(loc).__name__}")
    out = replay_into(loc, rec, reference_rng(seed, crowd_size), prior=start_prior(rec), measurement="scan", read="updates",
                      sensor=REFERENCE_SENSOR)  # fmt: skip
    assert out.updated is not None
    nees = consistency.run_nees(REFERENCE_LOCALIZER, out.estimates, rec.true_pose, out.covariances)
    return out.estimates, np.flatnonzero(out.updated).astype(np.int64), nees


def run_episode(task: EpisodeTask) -> Episode:
    """Record the episode, run ``far_point_mcl`` over it and keep its far-point scans, then the reference pass.

    Raises:
        RuntimeError: when the reference MCL weighed other steps than the far-point pass.
    """
    t0 = time.perf_counter()
    c0 = time.process_time()
    rec, crowd_xy = record_episode(task.seed, task.crowd_size, task.laps)
    t1 = time.perf_counter()
    log = _UpdateLog(rec, crowd_xy, task.snapshot)
    lidar = world.lidar_name()
    scan_map = rec.localizer_map("scan", lidar)
    loc = make_localizer("far_point_mcl", scan_map, dt_s=rec.dt_s, params={"mcl": pass_config().mcl_params()})
    if not isinstance(loc, FarPointMCL):
        raise TypeError(f"far_point_mcl built a {type(loc).__name__}")
    out = replay_into(loc, rec, episode_rng(task.seed, task.crowd_size), prior=start_prior(rec), measurement="scan",
                      read="updates", observer=log.observe, sensor=lidar)  # fmt: skip
    update_steps = np.asarray(log.steps, dtype=np.int64)
    t2 = time.perf_counter()
    reference, reference_steps, reference_nees = reference_pass(rec, task.seed, task.crowd_size)
    if not np.array_equal(reference_steps, update_steps):
        raise RuntimeError(f"episode seed {task.seed}: the reference MCL weighed other steps than the far-point pass")
    t3 = time.perf_counter()
    return Episode(
        task=task,
        recording=rec.without("lidar"),  # both LIDARs' leaves (by type): the replays need the update scans only
        scan_map=scan_map,
        update_steps=update_steps,
        raw_scans=log.lidar[update_steps].copy(),
        far_scans=np.stack(log.far),
        angles_rad=log.angles,
        max_range_m=log.max_range,
        pass_estimates=out.estimates[update_steps],
        reference_estimates=reference[update_steps],
        reference_nees=reference_nees[update_steps],
        beams={k: np.asarray(v, dtype=np.int64) for k, v in log.beams.items()},
        wall_bias_m={k: np.asarray(v) for k, v in log.bias.items()},
        accumulated_points=np.asarray(log.points, dtype=np.int64),
        window_increments=np.asarray(log.windows, dtype=np.float64).reshape(-1, 3),
        window_fixed=np.asarray(log.fixed, dtype=bool),
        contacts=int(rec.contacts.sum()),
        push_m=unexplained_motion_m(rec),
        snapshot=log.snapshot,
        record_s=t1 - t0,
        pass_s=t2 - t1,
        reference_s=t3 - t2,
        cpu_s=time.process_time() - c0,
    )


def episode_tasks(plan: Plan) -> list[EpisodeTask]:
    """The paper's crowd size for every seed (seed 0 keeps the Fig. 5 snapshot), then the other crowd sizes."""
    tasks = [EpisodeTask(s, CROWD_SIZE, plan.laps, snapshot=s == 0) for s in range(plan.seeds)]
    tasks += [EpisodeTask(s, n, plan.laps) for n in plan.densities if n != CROWD_SIZE for s in range(plan.seeds)]
    return tasks


# ------------------------------------------------------------------------------------ stage 2: replays


@dataclass(frozen=True)
class ChunkTask:
    """Replay one episode into several configurations."""

    episode: Episode
    configs: tuple[Config, ...]


@dataclass(frozen=True)
class Run:
    """One configuration on one episode, at its update steps.

    Attributes:
        key: the configuration's key.
        seed, crowd_size: the episode.
        estimates: ``(K, 3)``.
        errors_m: ``(K,)`` position errors against the true pose (ours).
        heading_errors_rad: ``(K,)`` absolute heading errors against the true pose.
        ref_errors_m: ``(K,)`` position errors against the reference pose (the paper's measure).
        ref_heading_errors_rad: ``(K,)`` absolute heading errors against the reference pose.
        nees: ``(K,)`` 3-dof pose NEES against the true pose (NaN: no usable covariance).
        cpu_s: CPU seconds of the replay.
    """

    key: str
    seed: int
    crowd_size: int
    estimates: Array
    errors_m: Array
    heading_errors_rad: Array
    ref_errors_m: Array
    ref_heading_errors_rad: Array
    nees: Array
    cpu_s: float = 0.0


def update_streams(episode: Episode) -> dict[bool, list[ScanMeasurement]]:
    """Per step, the scan each variant is fed: at an update step its scan, else the latest one.

    Between two update steps the MCL only checks the scan and ignores it (the caller
    verifies that it weighed exactly ``episode.update_steps``).
    """
    latest = np.searchsorted(episode.update_steps, np.arange(episode.recording.steps), side="right") - 1
    if latest[0] < 0:
        raise ValueError("update_streams: the first step must be an update step")
    out: dict[bool, list[ScanMeasurement]] = {}
    for far, table in ((False, episode.raw_scans), (True, episode.far_scans)):
        scans = [ScanMeasurement(np.asarray(r, dtype=np.float64), episode.angles_rad, episode.max_range_m) for r in table]
        out[far] = [scans[k] for k in latest]
    return out


def window_terms(episode: Episode, estimates: Array, params: LidarMCLParams) -> Array:
    """``(K, 3, 3)`` what ``far_point_mcl`` adds to its covariance at each update of ``episode``
    (``window_error``): :func:`localizers.scan_filter.window_covariance` of the last fix on the
    window's points, at the estimate then (``estimates``, ``(K, 3)``, this configuration's); zeros
    before the first fix or after one without a pose."""
    out = np.zeros((episode.update_steps.size, 3, 3))
    term = np.zeros((3, 3))
    for k in range(out.shape[0]):
        if episode.window_fixed[k]:
            pose = estimates[k]
            term = window_covariance(pose, episode.window_increments[k], params) if np.isfinite(pose).all() else np.zeros((3, 3))
        out[k] = term
    return out


def run_chunk(task: ChunkTask) -> list[Run]:
    """Replay ``mcl_lidar`` with each configuration on the episode's raw or far-point scans."""
    ep = task.episode
    rec = ep.recording
    deltas = odometry_deltas(rec)
    prior = start_prior(rec)
    streams = update_streams(ep)
    truth = rec.true_pose[ep.update_steps]
    ref = ep.reference_estimates
    runs = []
    window_error = world.far_point_defaults().window_error  # far_point_mcl's, as the pass ran it
    for c in task.configs:
        c0 = time.process_time()
        loc = make_localizer("mcl_lidar", ep.scan_map, dt_s=rec.dt_s, params=c.mcl_params())
        if not isinstance(loc, LidarMCL):
            raise TypeError(f"mcl_lidar built a {type(loc).__name__}")
        est, _, updated, cov = feed(loc, deltas, streams[c.far], episode_rng(ep.task.seed, ep.task.crowd_size),
                                    prior=prior, read="updates")  # fmt: skip
        if updated is None or not np.array_equal(np.flatnonzero(updated), ep.update_steps):
            raise RuntimeError(f"{c.key} on seed {ep.task.seed}: the MCL weighed other steps than the far-point pass")
        e = est[ep.update_steps]
        c_k = cov[ep.update_steps]
        if c.far and window_error:  # far_point_mcl's covariance
            c_k = c_k + window_terms(ep, e, loc.params)
        nees = consistency.run_nees(c.localizer, e, truth, c_k)
        runs.append(Run(c.key, ep.task.seed, ep.task.crowd_size, e, metrics.position_errors(e, truth),
                        metrics.heading_errors(e, truth), metrics.position_errors(e, ref), metrics.heading_errors(e, ref),
                        nees, time.process_time() - c0))  # fmt: skip
    return runs


def chunk_tasks(episodes: Sequence[Episode], plan: Plan) -> list[ChunkTask]:
    """The main configurations in chunks per main episode; the density pair per density episode."""
    main = plan.main_configs()
    density = both(DENSITY_PARAMS)
    tasks = []
    for ep in episodes:
        configs = main if ep.task.crowd_size == CROWD_SIZE else list(density)
        for i in range(0, len(configs), plan.chunk):
            tasks.append(ChunkTask(ep, tuple(configs[i : i + plan.chunk])))
    return sorted(tasks, key=lambda t: -len(t.configs) * t.episode.recording.steps)  # longest first


REFERENCE_KEY = "reference"  # the key of :func:`reference_runs`


def reference_runs(episodes: Sequence[Episode]) -> list[Run]:
    """The reference pose of each episode as a :class:`Run` against the truth (its errors
    against itself are zeros): how good the paper's yardstick is in our room."""
    out = []
    for ep in episodes:
        e, truth = ep.reference_estimates, ep.recording.true_pose[ep.update_steps]
        zeros = np.zeros(e.shape[0])
        out.append(Run(REFERENCE_KEY, ep.task.seed, ep.task.crowd_size, e, metrics.position_errors(e, truth),
                       metrics.heading_errors(e, truth), zeros, zeros.copy(), ep.reference_nees))  # fmt: skip
    return out


def pass_identity(episodes: Sequence[Episode], runs: Sequence[Run]) -> float:
    """Largest difference between each real ``far_point_mcl`` pass and its replay from the stored far-point scans.

    Raises:
        RuntimeError: when they differ (the replays would not be ``far_point_mcl``'s results).
    """
    key = pass_config().key
    by = {(r.seed, r.crowd_size): r for r in runs if r.key == key}
    worst = 0.0
    for ep in episodes:
        r = by.get((ep.task.seed, ep.task.crowd_size))
        if r is None:
            continue
        worst = max(worst, float(np.max(np.abs(r.estimates - ep.pass_estimates))))
    if worst != 0.0:
        raise RuntimeError(f"replayed far-point MCL differs from far_point_mcl by up to {worst} m")
    return worst


def run_all(plan: Plan, workers: int, ray_address: str | None) -> tuple[list[Episode], list[Run]]:
    """Both stages in worker processes (or on a Ray cluster): the episodes, then every replay."""
    episodes = run_tasks(run_episode, episode_tasks(plan), workers=workers, ray_address=ray_address,
                         desc="lidar-far-point: record + far-point and reference passes")  # fmt: skip
    chunks = run_tasks(run_chunk, chunk_tasks(episodes, plan), workers=workers, ray_address=ray_address,
                       desc="lidar-far-point: MCL replays")  # fmt: skip
    return episodes, [r for rs in chunks for r in rs]


# ------------------------------------------------------------------------------------ timing


def extraction_timing(episodes: Sequence[Episode], repeats: int = 5) -> tuple[int, float]:
    """Points and median seconds of one far-point extraction over the snapshot's accumulated points."""
    snap = next((ep.snapshot for ep in episodes if ep.snapshot is not None), None)
    if snap is None:
        return 0, float("nan")
    xy = snap.accumulated_xy
    bins = world.far_point_defaults().filter.bins
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        far_points(xy[:, 0], xy[:, 1], snap.pose[:2], float(snap.pose[2]), bins)
        times.append(time.perf_counter() - t)
    return int(xy.shape[0]), float(np.median(times))
