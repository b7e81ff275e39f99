"""Record one rollout, then replay its observation stream into any number of localizers.

:func:`record` steps an env with a scenario driver once and keeps, per step, every
sensor's observation array (a mapping by observation key) and the sensors' metadata, beside
the ground truth from ``info`` (true pose, truly visible landmarks, false detections,
contacts). :func:`replay` feeds the *observations only* to a localizer exactly as
:class:`envs.wrappers.LocalizationObservation` does online (``reset`` with an optional
known start pose, an update with the first frame, then ``predict`` and ``update`` per step),
so every localizer runs on identical data and the results equal the online wrapper's for the
same generator. Ground truth is used for the prior only when asked (``prior="start"``).
:func:`feed` is that stepping loop on its own, for measurement streams built elsewhere.

:func:`record_policy` records a closed loop instead: a policy acting on the observation as
``gym.make`` gives it, with the estimate of the localizer the env runs online where its keywords
name one (``localizer=...``); that estimate is kept beside the observations
(:attr:`Recording.estimates`), and replaying the same localizer with :func:`online_rng`
reproduces it.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import gymnasium as gym
import numpy as np
from numpy.typing import ArrayLike, NDArray

import envs  # noqa: F401  (registers the crowdloc ids)
from agents.experiments.scenarios import Driver
from envs.localization_env import LocalizationEnv
from envs.wrappers import _SEED_SALT
from localizers.base import BearingMeasurement, LandmarkMap, Localizer, OdometryDelta, PoseEstimate, ScanMeasurement
from localizers.measurements import decode, find_sensor, measurement_kind, odometry_delta, readable_kinds, sensor_map
from localizers.registry import make_localizer, measurement_in, spec

#: the covariance of the known start pose handed to localizers that need it (as the wrapper does)
PRIOR_COVARIANCE = np.diag([1e-6, 1e-6, 1e-6])


@dataclass(frozen=True)
class Recording:
    """One rollout: every sensor's observations and the ground truth, ``T`` steps (row 0 is the reset).

    Attributes:
        env_id: the env it came from.
        seed: the env seed.
        dt_s: time step.
        landmark_map: the map a localizer gets.
        observations: observation key -> ``(T, ...)`` float32 array of that sensor's readings.
        sensors: sensor name -> its metadata (``type``, observation ``key`` and what the
            sensor says about its readings: beam angles, noise, ...; see
            ``LocalizationEnv.sensor_metadata``).
        true_pose: ``(T, 3)`` ground truth.
        time_s: ``(T,)`` simulated time.
        visible: ``(T, L)`` landmarks truly in sight (before dropout).
        false_detections: ``(T, L)`` slots holding a random false detection.
        distractor_detections: ``(T, L)`` slots holding a distractor's bearing (a persistent
            false detection; the bearing camera's ``distractors``).
        contacts: ``(T,)`` contacts of our robot that began in each step.
        commanded: ``(T - 1, 3)`` the motion commanded in steps 1..T-1 (what the odometry
            measures before noise; contacts move the body beyond it).
        estimates: ``(T, 3)`` the estimate of the localizer the env ran online (``info["estimate"]``
            of ``gym.make(..., localizer=...)``), NaN where it claimed none; ``(0, 3)`` when the
            env ran none.
    """

    env_id: str
    seed: int
    dt_s: float
    landmark_map: LandmarkMap
    observations: Mapping[str, NDArray[np.float32]]
    sensors: Mapping[str, Mapping[str, Any]]
    true_pose: NDArray[np.float64]
    time_s: NDArray[np.float64]
    visible: NDArray[np.bool_]
    false_detections: NDArray[np.bool_]
    distractor_detections: NDArray[np.bool_]
    contacts: NDArray[np.int64]
    commanded: NDArray[np.float64] = field(default_factory=lambda: np.zeros((0, 3)))
    estimates: NDArray[np.float64] = field(default_factory=lambda: np.zeros((0, 3)))

    @property
    def steps(self) -> int:
        return int(self.true_pose.shape[0])

    def localizer_map(self, measurement: str, sensor: str | None = None) -> LandmarkMap:
        """The map a localizer reading ``measurement`` (a kind) gets: :attr:`landmark_map` as the
        recorded sensor of that kind (``sensor``, where there are several) sees it (cut at a
        range sensor's height), as the env wrapper gives it."""
        name = find_sensor(measurement, self.sensors, f"a {measurement} localizer on a recording of {self.env_id}", sensor)
        return sensor_map(self.landmark_map, self.sensors[name])

    def sensor_of(self, sensor_type: str) -> tuple[str, Mapping[str, Any]] | None:
        """``(name, metadata)`` of the first sensor of a registered type, or None."""
        for name, meta in self.sensors.items():
            if meta.get("type") == sensor_type:
                return name, meta
        return None

    def readings(self, sensor_type: str) -> NDArray[np.float32] | None:
        """``(T, ...)`` observations of the first sensor of ``sensor_type``, or None."""
        found = self.sensor_of(sensor_type)
        return None if found is None else self.observations[found[1]["key"]]

    def without(self, *sensor_types: str) -> Recording:
        """The same recording without the observations of these sensor types (to keep results small)."""
        drop = {name for name, meta in self.sensors.items() if meta.get("type") in sensor_types}
        keys = {self.sensors[name]["key"] for name in drop}
        return dataclasses.replace(
            self,
            observations={k: v for k, v in self.observations.items() if k not in keys},
            sensors={n: m for n, m in self.sensors.items() if n not in drop},
        )

    # -- the shipped sensors' readings by their usual names (views of ``observations``)
    @property
    def odometry(self) -> NDArray[np.float32]:
        """``(T, 3)`` odometry leaves (row 0: zeros, the reset observation)."""
        odo = self.readings("odometry")
        if odo is None:
            raise ValueError(f"the recording of {self.env_id} has no odometry")
        return odo

    @property
    def landmarks(self) -> NDArray[np.float32]:
        """``(T, 3 L)`` bearing-camera slots (``(T, 0)`` without a camera)."""
        slots = self.readings("bearing_camera")
        return np.zeros((self.steps, 0), dtype=np.float32) if slots is None else slots

    @property
    def lidar(self) -> NDArray[np.float32] | None:
        """``(T, B)`` LIDAR ranges, or None without a LIDAR."""
        return self.readings("lidar")

    @property
    def lidar_angles_rad(self) -> NDArray[np.float64] | None:
        """``(B,)`` LIDAR beam angles in the robot frame (None without a LIDAR)."""
        found = self.sensor_of("lidar")
        return None if found is None else np.asarray(found[1]["beam_angles_rad"], dtype=np.float64)

    @property
    def lidar_max_range_m(self) -> float:
        """The LIDAR's maximum range (0 without a LIDAR)."""
        found = self.sensor_of("lidar")
        return 0.0 if found is None else float(found[1]["max_range_m"])

    @property
    def camera_noise_std_rad(self) -> float:
        """The bearing camera's noise (0 without a camera)."""
        found = self.sensor_of("bearing_camera")
        return 0.0 if found is None else float(found[1]["noise_std_rad"])

    @property
    def odometry_alphas(self) -> tuple[float, float, float, float]:
        found = self.sensor_of("odometry")
        if found is None:
            raise ValueError(f"the recording of {self.env_id} has no odometry")
        return tuple(found[1]["alphas"])  # type: ignore[return-value]

    def detected(self, landmark_subset: Sequence[int] | None = None) -> NDArray[np.bool_]:
        """``(T, L)`` slots reported as seen (true or false detections), limited to a subset."""
        mask = self.landmarks.reshape(self.steps, -1, 3)[:, :, 0] > 0.5
        return mask & subset_mask(self.landmark_map.count, landmark_subset)


def subset_mask(count: int, landmark_subset: Sequence[int] | None) -> NDArray[np.bool_]:
    """``(L,)`` mask of the landmark ids a localizer may use (all when ``None``)."""
    mask = np.ones(count, dtype=bool)
    if landmark_subset is not None:
        ids = np.asarray(landmark_subset, dtype=np.int64)
        if ids.size and (ids.min() < 0 or ids.max() >= count):
            raise ValueError(f"landmark subset {ids.tolist()} out of range 0..{count - 1}")
        mask[:] = False
        mask[ids] = True
    return mask


def record(
    env_id: str,
    driver: Driver | Any,
    seed: int,
    *,
    max_steps: int,
    env_kwargs: Mapping[str, Any] | None = None,
    reset_options: Mapping[str, Any] | None = None,
) -> Recording:
    """Roll ``env_id`` out once with a scenario driver and keep what the sensors reported.

    Args:
        env_id: a registered crowdloc id.
        driver: a :class:`agents.experiments.scenarios.Driver`, or a callable ``env -> Driver`` (built
            after the env, for drivers that need its geometry).
        seed: the env seed.
        max_steps: stop after this many steps (also stops when the driver is done or the
            episode is truncated).
        env_kwargs: ``gym.make`` overrides (``crowd_size``, ``camera={...}``, ...).
        reset_options: passed to ``env.reset`` (``robot_pose``).
    """

    def start(env: gym.Env[Any, Any], base: LocalizationEnv) -> tuple[Callable[[Any], Any], Callable[[], bool]]:
        drv: Driver = driver if hasattr(driver, "act") else driver(base)  # type: ignore[operator]  # a Driver or a factory of one
        drv.reset(base)
        return (lambda _obs: drv.act(base)), (lambda: bool(drv.done))

    return _rollout(env_id, start, seed, max_steps, env_kwargs, reset_options)


def record_policy(
    env_id: str,
    make_policy: Callable[[gym.Env[Any, Any]], Any],
    seed: int,
    *,
    max_steps: int,
    env_kwargs: Mapping[str, Any] | None = None,
    reset_options: Mapping[str, Any] | None = None,
) -> Recording:
    """Roll ``env_id`` out once in a closed loop: a policy acting on the observation.

    The policy sees the observation as ``gym.make(env_id, **env_kwargs)`` gives it: where the
    keywords name a localizer (``localizer="mcl_lidar"``, ``localizer_params``, ``prior``), the
    env runs it online and the observation holds its estimate, never the truth. Its estimates are
    kept in :attr:`Recording.estimates`; the sensors' observations as :func:`record` keeps them.

    Args:
        env_id: a registered crowdloc id.
        make_policy: ``env -> policy`` (built after ``gym.make``, before the reset), the policy
            with ``predict(observation) -> (action, state)`` (:class:`agents.policies.base.FixedPolicy`).
        seed: the env seed (the online localizer's generator is :func:`online_rng` of it).
        max_steps: stop after this many steps (also stops when the episode ends).
        env_kwargs, reset_options: as for :func:`record`.
    """

    def start(env: gym.Env[Any, Any], base: LocalizationEnv) -> tuple[Callable[[Any], Any], Callable[[], bool]]:
        policy = make_policy(env)
        return (lambda obs: np.asarray(policy.predict(obs)[0], dtype=np.float32)), (lambda: False)

    return _rollout(env_id, start, seed, max_steps, env_kwargs, reset_options)


def online_rng(seed: int) -> np.random.Generator:
    """The generator the online wrapper (:class:`envs.wrappers.LocalizationObservation`)
    gives its localizer after ``env.reset(seed=seed)``: a replay drawing from it reproduces
    :attr:`Recording.estimates`."""
    return np.random.default_rng([seed, _SEED_SALT])


def _rollout(
    env_id: str,
    start: Callable[[gym.Env[Any, Any], LocalizationEnv], tuple[Callable[[Any], Any], Callable[[], bool]]],
    seed: int,
    max_steps: int,
    env_kwargs: Mapping[str, Any] | None,
    reset_options: Mapping[str, Any] | None,
) -> Recording:
    """The rollout of :func:`record` and :func:`record_policy`: ``start(env, base)`` after the
    reset gives ``act(observation) -> action`` and ``done() -> bool``."""
    env = gym.make(env_id, **dict(env_kwargs or {}))
    base = env.unwrapped
    assert isinstance(base, LocalizationEnv)
    sensors = base.sensor_metadata
    if not readable_kinds(sensors):
        raise ValueError(f"record: {env_id} has no sensor that a localizer reads (sensors: {', '.join(sensors)})")
    obs, info = env.reset(seed=seed, options=dict(reset_options) if reset_options else None)
    act, done = start(env, base)
    # a driver may have moved the ball or the crowd: observations are unchanged (the ball
    # does not occlude; parked members sit outside the field), the truth is re-read below
    no_landmarks = np.zeros(base.landmark_map.count, dtype=bool)
    keys = [str(meta["key"]) for meta in sensors.values()]
    observed: dict[str, list[NDArray[np.float32]]] = {key: [] for key in keys}
    truth: list[tuple[Any, ...]] = []
    estimates: list[NDArray[np.float64]] = []

    def keep(o: Mapping[str, Any], i: Mapping[str, Any]) -> None:
        for key in keys:
            observed[key].append(o[key].copy())
        vis = np.array(i.get("visible_landmarks", no_landmarks), dtype=bool)
        false = np.array(i.get("false_detections", no_landmarks), dtype=bool)
        fooled = np.array(i.get("distractor_detections", no_landmarks), dtype=bool)
        truth.append((np.asarray(i["true_pose"]).copy(), float(i["time_s"]), vis, false, len(i["contacts"]), fooled))
        est = i.get("estimate")
        if est is not None:
            estimates.append(np.array([est.x_m, est.y_m, est.theta_rad]) if est.valid else np.full(3, np.nan))

    keep(obs, info)
    commanded = []
    for _ in range(max_steps):
        if done():
            break
        action = act(obs)
        commanded.append(commanded_increment(action, base))
        obs, _, terminated, truncated, info = env.step(action)
        keep(obs, info)
        if terminated or truncated:
            break
    rec = Recording(
        env_id=env_id,
        seed=seed,
        dt_s=float(base.config.dt_s),
        landmark_map=base.landmark_map,
        observations={key: np.stack(rows) for key, rows in observed.items()},
        sensors=sensors,
        true_pose=np.stack([r[0] for r in truth]),
        time_s=np.array([r[1] for r in truth]),
        visible=np.stack([r[2] for r in truth]),
        false_detections=np.stack([r[3] for r in truth]),
        distractor_detections=np.stack([r[5] for r in truth]),
        contacts=np.array([r[4] for r in truth], dtype=np.int64),
        commanded=np.array(commanded, dtype=np.float64).reshape(-1, 3),
        estimates=np.array(estimates, dtype=np.float64).reshape(-1, 3),
    )
    env.close()
    return rec


def commanded_increment(action: NDArray[np.float32], env: LocalizationEnv) -> NDArray[np.float64]:
    """``(3,)`` the increment an action commands, as :meth:`LocalizationEnv.step` computes it:
    turn by ``omega dt`` while driving the chord of that arc."""
    dt = env.config.dt_s
    v = float(action[0]) * env.max_speed_mps
    omega = float(action[1]) * env.max_turn_rate_rps
    half = 0.5 * omega * dt
    return np.array([v * dt * np.cos(half), v * dt * np.sin(half), omega * dt])


def stream(recording: Recording, kind: str, sensor: str | None = None) -> list[Any]:
    """The ``T`` measurements of ``kind`` a localizer is fed, decoded from the observations only
    (:func:`localizers.measurements.decode`, with the recorded sensor metadata); ``sensor``
    names the sensor where the recording has several of the kind.

    Raises:
        ConfigError: if the recording has no (or, without ``sensor``, more than one) sensor that ``kind`` reads.
    """
    name = find_sensor(kind, recording.sensors, f"replay of {kind} measurements from {recording.env_id}", sensor)
    meta = recording.sensors[name]
    return [decode(kind, row, meta) for row in recording.observations[meta["key"]]]


def restricted(stream: Sequence[BearingMeasurement], count: int, landmark_subset: Sequence[int]) -> list[BearingMeasurement]:
    """Bearing measurements limited to the landmark ids of a subset (the others dropped)."""
    keep = subset_mask(count, landmark_subset)
    out = []
    for m in stream:
        sel = keep[m.landmark_ids]
        out.append(BearingMeasurement(m.landmark_ids[sel], m.bearings_rad[sel]))
    return out


def measurements(recording: Recording, landmark_subset: Sequence[int] | None = None) -> list[BearingMeasurement]:
    """The ``T`` bearing measurements a localizer is fed, built from the camera leaves only."""
    out = stream(recording, "bearings")
    return out if landmark_subset is None else restricted(out, recording.landmark_map.count, landmark_subset)


def scans(recording: Recording) -> list[ScanMeasurement]:
    """The ``T`` LIDAR scans a scan localizer is fed, built from the LIDAR leaves only."""
    return stream(recording, "scan")


def fed_slots(stream: Sequence[Any], count: int) -> NDArray[np.bool_]:
    """``(T, L)`` the landmark ids each measurement hands over (measurements that identify
    landmarks have ``landmark_ids``; others hand over none)."""
    fed = np.zeros((len(stream), count), dtype=bool)
    for t, m in enumerate(stream):
        ids = getattr(m, "landmark_ids", None)
        if ids is not None:
            fed[t, ids] = True
    return fed


def odometry_deltas(recording: Recording) -> list[OdometryDelta]:
    """The ``T - 1`` odometry increments a localizer is fed (steps 1..T-1), from the odometry leaves."""
    return [odometry_delta(d) for d in recording.odometry[1:]]


@dataclass(frozen=True)
class ReplayResult:
    """A localizer's answers along a recording.

    Attributes:
        estimates: ``(T, 3)`` poses, NaN where the estimate was invalid (or not read).
        valid: ``(T,)`` whether the localizer claimed a pose.
        fed: ``(T, L)`` landmark slots handed to it (true or false detections; ``(T, 0)``
            for scans).
        covariances: ``(T, 3, 3)`` the reported covariances of the estimates (NaN where the
            estimate is NaN, or its covariance is not ``3 x 3``), for
            :func:`agents.evaluate.metrics.pose_nees`.
        updated: ``(T,)`` steps at which the localizer weighed its measurement, for
            localizers that count their updates (an ``updates`` attribute), else None.
    """

    estimates: NDArray[np.float64]
    valid: NDArray[np.bool_]
    fed: NDArray[np.bool_]
    covariances: NDArray[np.float64]
    updated: NDArray[np.bool_] | None = None


def start_prior(recording: Recording) -> PoseEstimate:
    """The known initial pose (the paper's baselines (1) and (3) start from it)."""
    x, y, theta = recording.true_pose[0]
    return PoseEstimate(float(x), float(y), float(theta), PRIOR_COVARIANCE.copy(), True)


def feed(
    localizer: Localizer,
    deltas: Sequence[OdometryDelta],
    stream: Sequence[Any],
    rng: np.random.Generator,
    *,
    prior: PoseEstimate | None = None,
    read: str = "every_step",
    observer: Callable[[int, Localizer, bool], None] | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.bool_], NDArray[np.bool_] | None, NDArray[np.float64]]:
    """Step a localizer through a measurement stream as the online wrapper does.

    ``reset(rng, prior)``, ``update(stream[0])``, then per step ``t >= 1``
    ``predict(deltas[t - 1])`` and ``update(stream[t])``.

    Args:
        localizer: any :class:`localizers.base.Localizer`.
        deltas: ``T - 1`` odometry increments.
        stream: ``T`` measurements.
        rng: the localizer's own generator.
        prior: handed to ``reset``.
        read: ``"every_step"`` reads the estimate after every update call; ``"updates"``
            only at the steps where the localizer weighed its measurement (needs an
            ``updates`` counter; the other rows stay NaN and invalid). Reading is free of
            side effects, so both give the same estimates where both read.
        observer: called as ``observer(t, localizer, weighed)`` after each step (a tap for
            figures; it must not change the localizer).

    Returns:
        ``(T, 3)`` estimates (NaN where invalid or not read), ``(T,)`` validity, the
        ``(T,)`` steps at which the measurement was weighed (None without an ``updates``
        counter) and the ``(T, 3, 3)`` covariances of the estimates (NaN where there is none).
    """
    if read not in ("every_step", "updates"):
        raise ValueError(f"read must be 'every_step' or 'updates', got {read!r}")
    T = len(stream)
    if len(deltas) != T - 1:
        raise ValueError(f"feed: {T} measurements need {T - 1} odometry increments, got {len(deltas)}")
    counts = hasattr(localizer, "updates")
    if read == "updates" and not counts:
        raise ValueError(f"feed: read='updates' needs a localizer with an updates counter, got {type(localizer).__name__}")
    est = np.full((T, 3), np.nan)
    valid = np.zeros(T, dtype=bool)
    updated = np.zeros(T, dtype=bool)
    cov = np.full((T, 3, 3), np.nan)
    localizer.reset(rng, prior)
    for t in range(T):
        if t:
            localizer.predict(deltas[t - 1])
        before = localizer.updates if counts else 0  # type: ignore[attr-defined]
        localizer.update(stream[t])
        weighed = counts and localizer.updates != before  # type: ignore[attr-defined]
        updated[t] = weighed
        if read == "every_step" or weighed:
            e = localizer.estimate
            if e.valid:
                valid[t] = True
                est[t] = (e.x_m, e.y_m, e.theta_rad)
                if np.shape(e.covariance) == (3, 3):
                    cov[t] = e.covariance
        if observer is not None:
            observer(t, localizer, weighed)
    return est, valid, updated if counts else None, cov


def replay_into(
    localizer: Localizer,
    recording: Recording,
    rng: np.random.Generator,
    *,
    prior: PoseEstimate | None = None,
    landmark_subset: Sequence[int] | None = None,
    measurement: str = "bearings",
    read: str = "every_step",
    observer: Callable[[int, Localizer, bool], None] | None = None,
    sensor: str | None = None,
) -> ReplayResult:
    """Feed a recording's observation leaves to ``localizer``, as the online wrapper does.

    Args:
        localizer: any :class:`localizers.base.Localizer`.
        recording: from :func:`record`.
        rng: the localizer's own generator.
        prior: handed to ``reset`` (``None``: the localizer starts without a pose).
        landmark_subset: landmark ids it may use; bearings to others are dropped.
        measurement: a registered measurement kind (``"bearings"``: the camera's slots;
            ``"scan"``: the LIDAR's ranges), decoded from the sensor it reads.
        read, observer: see :func:`feed`.
        sensor: the sensor it reads, where the recording has several of the kind.
    """
    fed_stream: list[Any] = stream(recording, measurement, sensor)
    if landmark_subset is not None:
        if measurement_kind(measurement).sensor_type != "bearing_camera":
            raise ValueError(f"landmark_subset applies to bearing measurements, not {measurement!r}")
        fed_stream = restricted(fed_stream, recording.landmark_map.count, landmark_subset)
    fed = fed_slots(fed_stream, recording.landmark_map.count)
    est, valid, updated, cov = feed(localizer, odometry_deltas(recording), fed_stream, rng, prior=prior, read=read,
                                    observer=observer)  # fmt: skip
    return ReplayResult(est, valid, fed, cov, updated)


def replay(
    recording: Recording,
    name: str,
    *,
    rng_seed: int | Sequence[int],
    params: Mapping[str, Any] | None = None,
    landmark_subset: Sequence[int] | None = None,
    prior: str = "auto",
    read: str = "every_step",
    sensor: str | None = None,
) -> ReplayResult:
    """Build registered localizer ``name`` and replay ``recording`` into it.

    Args:
        recording: from :func:`record`.
        name: a registered localizer.
        rng_seed: seeds the localizer's generator (``np.random.default_rng(rng_seed)``).
        params: overrides of its YAML parameters.
        landmark_subset: landmark ids it may use.
        prior: ``"start"`` (the true start pose), ``"none"``, or ``"auto"``: what the
            registry says the method needs.
        read: see :func:`feed`.
        sensor: the sensor it reads, where the recording has several of its kind (a second LIDAR).
    """
    if prior not in ("auto", "start", "none"):
        raise ValueError(f"prior must be 'auto', 'start' or 'none', got {prior!r}")
    entry = spec(name)
    needs = entry.needs_prior if prior == "auto" else prior == "start"
    kind = entry.measurement if sensor is not None else measurement_in(name, recording.sensors)
    localizer = make_localizer(name, recording.localizer_map(kind, sensor), dt_s=recording.dt_s, params=params)
    return replay_into(
        localizer,
        recording,
        np.random.default_rng(rng_seed),
        prior=start_prior(recording) if needs else None,
        landmark_subset=landmark_subset,
        measurement=kind,
        read=read,
        sensor=sensor,
    )


def bound_rmse_along(
    true_pose: ArrayLike,
    odometry: ArrayLike,
    visible: ArrayLike,
    landmarks_xy: ArrayLike,
    bearing_std_rad: float,
    alphas: Sequence[float],
    *,
    known_start: bool,
    bounds_m: tuple[float, float, float, float],
) -> NDArray[np.float64]:
    """``(T,)`` posterior-CRB position RMSE along a true path (NaN for a noise-free camera).

    Args:
        true_pose: ``(T, 3)``; odometry: ``(T - 1, 3)`` increments; visible: ``(T, L)`` mask.
        landmarks_xy: ``(L, 2)``; bearing_std_rad: the camera noise; alphas: odometry alpha1..4.
        known_start: prior = the known start pose, else uniform over the field and heading.
        bounds_m: ``(xmin, ymin, xmax, ymax)`` of the field.
    """
    from localizers.bounds import bound_position_rmse, posterior_crb

    truth = np.asarray(true_pose, dtype=np.float64)
    if not bearing_std_rad > 0:
        return np.full(truth.shape[0], np.nan)
    xmin, ymin, xmax, ymax = bounds_m
    vague = np.diag([(xmax - xmin) ** 2 / 12.0, (ymax - ymin) ** 2 / 12.0, math.pi**2 / 3.0])
    cov = posterior_crb(truth, odometry, np.asarray(visible, dtype=bool), landmarks_xy, bearing_std_rad, alphas,
                        PRIOR_COVARIANCE if known_start else vague)  # fmt: skip
    return bound_position_rmse(cov)
