"""The runs: per seed one map (run 1); per seed and crowd size one run 2, recorded once and replayed into every localizer.

Run 1 is :func:`agents.experiments.scene_maps.build_scene_map`: ``route_follower`` drives the campus route
on the LIDAR reference's estimate at the world's crowd size and a scene is stored every second,
its pose the reference's estimate (the paper's map poses came from its amcl too).

Run 2 (:func:`run_episode`) is another crowd on the same route at a crowd size of the sweep:
``route_follower`` drives it on the LIDAR reference run online (``mcl_lidar`` with
:data:`agents.experiments.scene_maps.AMCL_LIKE`; the driver never reads the truth), and the rollout is
recorded once (:func:`agents.experiments.replay.record_policy`). Then every localizer is replayed into the
same recording (:func:`agents.experiments.replay.replay_into`): ``far_landmark_pf`` with each selection on
the stereo edges (the measurement kind ``stereo_edges``), all from one generator and the seed's
map, and ``mcl_lidar`` on the LIDAR's scans with the online wrapper's generator, whose estimates
must equal the online ones that drove the robot bit for bit (:attr:`Episode.identity_m`).
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from agents.common.sweep import run_tasks
from agents.evaluate.consistency import run_nees
from agents.experiments.replay import Recording, ReplayResult, online_rng, record_policy, replay_into, start_prior
from agents.experiments.scene_maps import AMCL_LIKE, MappingDrive, build_scene_map, camera_signature, rig_timing
from agents.policies import make_policy
from localizers.far_landmark_pf import FarLandmarkPF
from localizers.far_landmark_pf.scene_map import SceneMap
from localizers.measurements import edge_measurement
from localizers.registry import load_params, make_localizer

from . import world
from .experiment import (
    ENV_ID,
    MAP_SEED_OFFSET,
    NEAR_M,
    PAPER_SELECTION,
    PF_RNG_SALT,
    REFERENCE_KEY,
    SELECTIONS,
    Plan,
    pf_params,
    reference_env_kwargs,
)

Array = NDArray[np.float64]

# ------------------------------------------------------------------------------------ run 1: the maps


@dataclass(frozen=True)
class MapTask:
    """Run 1 of a seed."""

    seed: int
    crowd_size: int
    max_steps: int | None = None


@dataclass(frozen=True)
class MapResult:
    """A seed's scene map and what making it took."""

    task: MapTask
    scenes: SceneMap
    seconds: float


def map_drive(task: MapTask) -> MappingDrive:
    """The mapping drive of a seed: its own crowd (:data:`MAP_SEED_OFFSET`), poses from the LIDAR reference."""
    return MappingDrive(seed=MAP_SEED_OFFSET + task.seed, crowd_size=task.crowd_size, pose="reference", max_steps=task.max_steps)


def make_map(task: MapTask) -> MapResult:
    t0 = time.perf_counter()
    scenes = build_scene_map(world.WORLD, map_drive(task))
    return MapResult(task, scenes, time.perf_counter() - t0)


# ------------------------------------------------------------------------------------ run 2


@dataclass(frozen=True)
class EpisodeTask:
    """Run 2 of a seed at a crowd size, localized on the seed's map."""

    seed: int
    crowd_size: int
    scenes: SceneMap
    max_steps: int | None = None


@dataclass(frozen=True)
class Episode:
    """One recorded run 2 and every localizer's answers along it (``T`` steps).

    Attributes:
        seed, crowd_size: the run.
        time_s: ``(T,)``; truth: ``(T, 3)`` the true pose.
        arc_m: ``(T,)`` the arc length of the route point nearest the true position.
        estimates: localizer key (:data:`.experiment.KEYS`) -> ``(T, 3)`` its estimates, NaN where it claimed none.
        nees: localizer key -> ``(T,)`` the NEES of its estimate against the truth under its reported
            covariance (:func:`agents.evaluate.consistency.run_nees`; NaN where it claimed no pose).
        detections: ``(T,)`` the stereo camera's matched edges a frame (its valid slots).
        far_detections: ``(T,)`` those at least far emphasis's ``min_range_m`` away.
        used: ``(T,)`` the detections the paper's far emphasis weighed a frame (for its estimate's pose).
        near_beams: ``(T,)`` the LIDAR's beams returning within ``NEAR_M`` (the crowd near the robot, over the static scene).
        identity_m: the largest difference between the replayed reference and the online one that
            drove the robot (0: the replay is that run).
        reached_goal: the episode ended at the route's goal.
        contacts: contacts of our robot.
        blocked_s: seconds route_follower stood still for an obstacle.
        record_s, replay_s: seconds of the recording and of each localizer's replay.
        cpu_s: CPU seconds of the task.
    """

    seed: int
    crowd_size: int
    time_s: Array
    truth: Array
    arc_m: Array
    estimates: dict[str, Array]
    detections: NDArray[np.int64]
    far_detections: NDArray[np.int64]
    used: NDArray[np.int64]
    near_beams: NDArray[np.int64]
    identity_m: float
    reached_goal: bool
    contacts: int
    blocked_s: float
    record_s: float = 0.0
    nees: dict[str, Array] = field(default_factory=dict)
    replay_s: dict[str, float] = field(default_factory=dict)
    cpu_s: float = 0.0

    @property
    def steps(self) -> int:
        return int(self.truth.shape[0])


def arc_length(xy: Array, route: Array) -> Array:
    """``(T,)`` the arc length of the route point nearest each of ``xy`` ``(T, 2)``."""
    a, b = route[:-1], route[1:]
    d = b - a
    cum = np.concatenate([[0.0], np.cumsum(np.hypot(d[:, 0], d[:, 1]))])
    rel = xy[:, None, :] - a[None]
    t = np.clip(np.einsum("tsk,sk->ts", rel, d) / np.einsum("sk,sk->s", d, d)[None], 0.0, 1.0)
    near = a[None] + t[..., None] * d[None]
    dist = np.hypot(*(near - xy[:, None, :]).transpose(2, 0, 1))
    k = np.argmin(dist, axis=1)
    rows = np.arange(xy.shape[0])
    return np.asarray(cum[k] + t[rows, k] * (cum[k + 1] - cum[k]), dtype=np.float64)


def record_run(seed: int, crowd_size: int, max_steps: int | None) -> tuple[Recording, Any]:
    """Run 2: route_follower on the online LIDAR reference, recorded once; returns the recording and the policy."""
    made: list[Any] = []

    def policy(env: Any) -> Any:
        made.append(make_policy("route_follower", env, seed=seed))
        return made[0]

    steps = max_steps or world.campus().max_episode_steps
    rec = record_policy(ENV_ID, policy, seed, max_steps=steps, env_kwargs=reference_env_kwargs(crowd_size))
    return rec, made[0]


def reference_replay(rec: Recording) -> ReplayResult:
    """The LIDAR reference replayed into the recording with the online wrapper's generator."""
    lidar = world.lidar_name()
    loc = make_localizer(world.REFERENCE, rec.localizer_map("scan", lidar), dt_s=rec.dt_s, params=AMCL_LIKE)
    return replay_into(loc, rec, online_rng(rec.seed), prior=start_prior(rec), measurement="scan", sensor=lidar)


def pf_rng(seed: int, crowd_size: int) -> np.random.Generator:
    """far_landmark_pf's generator of a run (the same for every selection)."""
    return np.random.default_rng([seed, crowd_size, PF_RNG_SALT])


def far_landmark_pf(rec: Recording, scenes: SceneMap, selection: str) -> FarLandmarkPF:
    """far_landmark_pf with ``selection`` on the seed's map (checked against the recorded world and camera)."""
    camera = world.camera_name()
    landmarks = rec.localizer_map("stereo_edges", camera)
    scenes.check_world(landmarks, world.WORLD, camera_signature(rec.sensors[camera]))
    params = {**rig_timing(rec.sensors[camera]), **pf_params(selection)}  # the camera's frame gap, as gym.make gives it
    return FarLandmarkPF(landmarks, load_params(world.LOCALIZER, params), dt_s=rec.dt_s, scenes=scenes)


def detection_counts(rec: Recording, min_range_m: float) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """``(T,)`` the camera's matched edges a frame, and those at least ``min_range_m`` away."""
    slots = rec.observations[str(rec.sensors[world.camera_name()]["key"])]
    total, far = [], []
    for row in slots:
        m = edge_measurement(row)
        total.append(m.types.size)
        far.append(int(np.count_nonzero(1.0 / m.inverse_range_m >= min_range_m)))
    return np.asarray(total, dtype=np.int64), np.asarray(far, dtype=np.int64)


def run_episode(task: EpisodeTask) -> Episode:
    """Record run 2 once, replay every localizer into it (module docstring).

    Raises:
        RuntimeError: when the replayed reference differs from the online one that drove the robot.
    """
    t0, c0 = time.perf_counter(), time.process_time()
    rec, policy = record_run(task.seed, task.crowd_size, task.max_steps)
    record_s = time.perf_counter() - t0
    estimates: dict[str, Array] = {}
    nees: dict[str, Array] = {}
    replay_s: dict[str, float] = {}
    used: list[int] = []

    def count_used(t: int, localizer: Any, weighed: bool) -> None:
        used.append(int(localizer.used_xy.shape[0]))

    prior = start_prior(rec)
    for selection in SELECTIONS:
        t = time.perf_counter()
        pf = far_landmark_pf(rec, task.scenes, selection)
        observer = count_used if selection == PAPER_SELECTION else None
        out = replay_into(pf, rec, pf_rng(task.seed, task.crowd_size), prior=prior, measurement="stereo_edges",
                          sensor=world.camera_name(), observer=observer)  # fmt: skip
        estimates[selection] = out.estimates
        nees[selection] = run_nees(world.LOCALIZER, out.estimates, rec.true_pose, out.covariances)
        replay_s[selection] = time.perf_counter() - t
    t = time.perf_counter()
    ref = reference_replay(rec)
    estimates[REFERENCE_KEY] = ref.estimates
    nees[REFERENCE_KEY] = run_nees(world.REFERENCE, ref.estimates, rec.true_pose, ref.covariances)
    replay_s[REFERENCE_KEY] = time.perf_counter() - t
    online = rec.estimates
    if online.shape != estimates[REFERENCE_KEY].shape or not np.array_equal(online, estimates[REFERENCE_KEY], equal_nan=True):
        diff = np.nanmax(np.abs(online - estimates[REFERENCE_KEY])) if online.shape == estimates[REFERENCE_KEY].shape else np.inf
        raise RuntimeError(f"run 2 seed {task.seed}, crowd {task.crowd_size}: the replayed reference differs from the "
                           f"online one that drove the robot (by up to {diff} m)")  # fmt: skip
    total, far = detection_counts(rec, world.far_landmark_defaults().min_range_m)
    goal = world.campus().goal
    end = rec.true_pose[-1]
    reached = goal is not None and bool(np.hypot(end[0] - goal.x_m, end[1] - goal.y_m) <= goal.radius_m)
    return Episode(
        seed=task.seed,
        crowd_size=task.crowd_size,
        time_s=rec.time_s.copy(),
        truth=rec.true_pose.copy(),
        arc_m=arc_length(rec.true_pose[:, :2], world.route()),
        estimates=estimates,
        nees=nees,
        detections=total,
        far_detections=far,
        used=np.asarray(used, dtype=np.int64),
        near_beams=np.count_nonzero(rec.observations[str(rec.sensors[world.lidar_name()]["key"])] < NEAR_M, axis=1).astype(
            np.int64
        ),
        identity_m=0.0,
        reached_goal=reached,
        contacts=int(rec.contacts.sum()),
        blocked_s=policy.blocked_steps * rec.dt_s,
        record_s=record_s,
        replay_s=replay_s,
        cpu_s=time.process_time() - c0,
    )


def map_tasks(plan: Plan) -> list[MapTask]:
    return [MapTask(s, plan.crowd, plan.max_steps) for s in range(plan.seeds)]


def episode_tasks(plan: Plan, maps: Sequence[MapResult]) -> list[EpisodeTask]:
    """Every (seed, crowd size), the denser crowds first (they take longest)."""
    by_seed = {m.task.seed: m.scenes for m in maps}
    tasks = [EpisodeTask(s, n, by_seed[s], plan.max_steps) for n in plan.densities for s in range(plan.seeds)]
    return sorted(tasks, key=lambda t: -t.crowd_size)


def run_all(plan: Plan, workers: int, ray_address: str | None = None) -> tuple[list[MapResult], list[Episode]]:
    """Both stages in worker processes: the maps, then every run 2 with its replays."""
    maps = run_tasks(make_map, map_tasks(plan), workers=workers, ray_address=ray_address,
                     desc="stereo-far-landmarks: run 1 (maps)")  # fmt: skip
    episodes = run_tasks(run_episode, episode_tasks(plan, maps), workers=workers, ray_address=ray_address,
                         desc="stereo-far-landmarks: run 2 (record + replays)")  # fmt: skip
    return maps, sorted(episodes, key=lambda e: (e.crowd_size, e.seed))
