"""agents.experiments.replay: replaying a recording equals the online wrapper, and feeds observation leaves only."""

from __future__ import annotations

import dataclasses
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import envs  # noqa: F401
from agents.evaluate import metrics
from agents.experiments.replay import Recording, measurements, odometry_deltas, record, replay, replay_into, scans
from agents.experiments.scenarios import SoccerDriver, exp1_driver, square_driver
from envs.wrappers import _SEED_SALT, bearing_measurement
from localizers.base import BearingMeasurement, OdometryDelta, Overlay, PoseEstimate
from localizers.registry import LOCALIZERS
from tests.envs.exact import EXACT

BEARING_LOCALIZERS = sorted(name for name, s in LOCALIZERS.items() if s.measurement == "bearings")
SOCCER = {"crowd_size": 1, "camera": {"dropout_probability": 0.5}}
START = [0.0, 3.0, 0.0]


def exp1(max_steps: int = 300, **kwargs: Any) -> Recording:
    return record("crowdloc/RoboCupStatic-v0", exp1_driver, seed=4, max_steps=max_steps, env_kwargs=kwargs)


def soccer(max_steps: int = 200) -> Recording:
    return record("crowdloc/RoboCupCrowded-v0", SoccerDriver(seed=5), seed=5, max_steps=max_steps, env_kwargs=SOCCER,
                  reset_options={"robot_pose": START})  # fmt: skip


@pytest.fixture(scope="module")
def recordings() -> dict[str, Recording]:
    return {"exp1": exp1(), "soccer": soccer()}


def online(case: str, name: str) -> np.ndarray:
    """Estimates ``(T, 3)`` of ``gym.make(id, localizer=name)`` driven like the recording."""
    if case == "exp1":
        env = gym.make("crowdloc/RoboCupStatic-v0", localizer=name)
        seed, options, steps = 4, None, 300
        _, info = env.reset(seed=seed, options=options)
        driver: Any = exp1_driver(env.unwrapped)
    else:
        env = gym.make("crowdloc/RoboCupCrowded-v0", localizer=name, **SOCCER)
        seed, options, steps = 5, {"robot_pose": START}, 200
        _, info = env.reset(seed=seed, options=options)
        driver = SoccerDriver(seed=5)
    driver.reset(env.unwrapped)
    out = [claimed(info["estimate"])]
    for _ in range(steps):
        _, _, _, _, info = env.step(driver.act(env.unwrapped))
        out.append(claimed(info["estimate"]))
    env.close()
    return np.array(out)


def claimed(estimate: PoseEstimate) -> np.ndarray:
    """The pose an estimate claims, NaN where it claims none (as a replay records it: a localizer
    that stops claiming may still hold a mean)."""
    return estimate.as_array() if estimate.valid else np.full(3, np.nan)


@pytest.mark.parametrize("case", ["exp1", "soccer"])
@pytest.mark.parametrize("name", BEARING_LOCALIZERS)
def test_replay_equals_the_online_wrapper(recordings: dict[str, Recording], case: str, name: str) -> None:
    rec = recordings[case]
    seed = rec.seed
    replayed = replay(rec, name, rng_seed=[seed, _SEED_SALT])
    np.testing.assert_array_equal(replayed.estimates, online(case, name))
    assert replayed.valid.any()


class Spy:
    """A localizer that only remembers what it was fed."""

    def __init__(self) -> None:
        self.prior: PoseEstimate | None = None
        self.deltas: list[np.ndarray] = []
        self.fed: list[BearingMeasurement] = []

    def reset(self, rng: np.random.Generator, prior: PoseEstimate | None = None) -> None:
        self.prior = prior

    def predict(self, odometry: OdometryDelta) -> None:
        self.deltas.append(odometry.as_array())

    def update(self, measurement: BearingMeasurement) -> None:
        self.fed.append(measurement)

    @property
    def estimate(self) -> PoseEstimate:
        return PoseEstimate.invalid()

    def overlay(self) -> Overlay:
        return Overlay()


def test_localizers_are_fed_observation_leaves_only(recordings: dict[str, Recording]) -> None:
    rec = recordings["soccer"]
    spy = Spy()
    replay_into(spy, rec, np.random.default_rng(0))
    assert spy.prior is None
    np.testing.assert_array_equal(np.array(spy.deltas), rec.odometry[1:].astype(np.float64))
    assert len(spy.fed) == rec.steps
    for slots, m in zip(rec.landmarks, spy.fed):
        expected = bearing_measurement(slots)
        np.testing.assert_array_equal(m.landmark_ids, expected.landmark_ids)
        np.testing.assert_array_equal(m.bearings_rad, expected.bearings_rad)
    assert sum(m.landmark_ids.size for m in spy.fed) == rec.detected().sum() > 0


@pytest.mark.parametrize("name", [n for n in BEARING_LOCALIZERS if not LOCALIZERS[n].needs_prior])
def test_replay_never_reads_the_true_pose(recordings: dict[str, Recording], name: str) -> None:
    rec = recordings["soccer"]
    scrambled = dataclasses.replace(rec, true_pose=np.random.default_rng(1).uniform(-9, 9, rec.true_pose.shape))
    a = replay(rec, name, rng_seed=[1, 2])
    b = replay(scrambled, name, rng_seed=[1, 2])
    np.testing.assert_array_equal(a.estimates, b.estimates)


@pytest.mark.parametrize("name", BEARING_LOCALIZERS)
def test_known_start_goes_only_to_methods_that_need_it(
    recordings: dict[str, Recording], name: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    rec = recordings["exp1"]
    seen: list[PoseEstimate | None] = []

    def capture(localizer: Any, recording: Recording, rng: np.random.Generator, **kwargs: Any) -> None:
        seen.append(kwargs["prior"])

    monkeypatch.setattr("agents.experiments.replay.replay_into", capture)
    replay(rec, name, rng_seed=0)
    replay(rec, name, rng_seed=0, prior="none")
    replay(rec, name, rng_seed=0, prior="start")
    auto, none, start = seen
    assert none is None and start is not None
    np.testing.assert_array_equal(start.as_array(), rec.true_pose[0])
    assert (auto is not None) == LOCALIZERS[name].needs_prior


def test_landmark_subset_drops_the_other_bearings(recordings: dict[str, Recording]) -> None:
    rec = recordings["exp1"]
    fed = measurements(rec, landmark_subset=[1, 2])
    assert all(set(m.landmark_ids.tolist()) <= {1, 2} for m in fed)
    assert sum(0 in m.landmark_ids for m in measurements(rec)) > 0  # L5 was seen, and dropped
    out = replay(rec, "candidate_sets", rng_seed=0, landmark_subset=[1, 2])
    assert not out.fed[:, 0].any() and out.fed[:, 1:].any()
    assert len(odometry_deltas(rec)) == rec.steps - 1
    with pytest.raises(ValueError, match="out of range"):
        measurements(rec, landmark_subset=[7])


def test_noise_free_exp1_candidate_sets_fix_within_5_cm() -> None:
    noise_free = {
        "camera": {"noise_std_rad": 0.0},
        "odometry": {"alpha1": 0.0, "alpha2": 0.0, "alpha3": 0.0, "alpha4": 0.0, **EXACT},
    }
    rec = exp1(max_steps=10_000, **noise_free)
    out = replay(rec, "candidate_sets", rng_seed=0, landmark_subset=[1, 2])
    ff = metrics.first_fix(out.valid)
    assert ff is not None and metrics.travelled(rec.true_pose)[ff] < 2.0
    err = metrics.position_errors(out.estimates, rec.true_pose)
    assert metrics.mean_sd(err, ff)[0] < 0.05


SCAN_LOCALIZERS = sorted(name for name, s in LOCALIZERS.items() if s.measurement == "scan")
ROOM_START = [2.5, 2.5, 0.0]


def room_driver(env: Any) -> Any:
    return square_driver(env, center_xy=(3.5, 3.5), side_m=2.0, laps=1, speed_mps=0.5, turn_rate_rps=1.0)


@pytest.fixture(scope="module")
def room() -> Recording:
    return record("crowdloc/CrowdedRoom-v0", room_driver, seed=6, max_steps=400, reset_options={"robot_pose": ROOM_START})


@pytest.mark.parametrize("name", SCAN_LOCALIZERS)
def test_scan_replay_equals_the_online_wrapper(room: Recording, name: str) -> None:
    env = gym.make("crowdloc/CrowdedRoom-v0", localizer=name)
    _, info = env.reset(seed=6, options={"robot_pose": ROOM_START})
    driver = room_driver(env.unwrapped)
    driver.reset(env.unwrapped)
    online = [claimed(info["estimate"])]
    for _ in range(room.steps - 1):
        _, _, _, _, info = env.step(driver.act(env.unwrapped))
        online.append(claimed(info["estimate"]))
    env.close()
    replayed = replay(room, name, rng_seed=[6, _SEED_SALT])
    np.testing.assert_array_equal(replayed.estimates, np.array(online))
    assert replayed.updated is not None and 3 <= replayed.updated.sum() < room.steps
    assert replayed.fed.shape == (room.steps, 0)
    # reading only at the updates changes nothing where both read
    sparse = replay(room, name, rng_seed=[6, _SEED_SALT], read="updates")
    np.testing.assert_array_equal(sparse.estimates[sparse.updated], replayed.estimates[replayed.updated])
    assert np.isnan(sparse.estimates[~sparse.updated]).all()


def test_scans_are_the_lidar_leaves(room: Recording) -> None:
    assert room.lidar is not None and room.lidar_angles_rad is not None and room.landmarks.shape == (room.steps, 0)
    fed = scans(room)
    assert len(fed) == room.steps and fed[5].max_range_m == room.lidar_max_range_m == 30.0
    np.testing.assert_array_equal(fed[5].ranges_m, room.lidar[5].astype(np.float64))
    np.testing.assert_array_equal(fed[5].angles_rad, room.lidar_angles_rad)
    with pytest.raises(ValueError, match="needs a lidar sensor"):
        scans(exp1(max_steps=3))


def test_a_recording_holds_every_sensor_by_key_with_its_metadata(room: Recording) -> None:
    assert set(room.observations) == {"odometry", "lidar"}
    assert {name: meta["type"] for name, meta in room.sensors.items()} == {"odometry": "odometry", "lidar": "lidar"}
    assert room.observations["lidar"].shape == (room.steps, 1081) and room.observations["lidar"].dtype == np.float32
    smaller = room.without("lidar")
    assert set(smaller.observations) == {"odometry"} and smaller.lidar is None and room.lidar is not None
    with pytest.raises(ValueError, match="updates counter"):
        replay(exp1(max_steps=3), "candidate_sets", rng_seed=0, read="updates")


class Blinker(Spy):
    """A localizer with a pose every other step, its covariance ``(t + 1) I`` at step ``t``."""

    def __init__(self) -> None:
        super().__init__()
        self.t = -1

    def update(self, measurement: BearingMeasurement) -> None:
        self.t += 1

    @property
    def estimate(self) -> PoseEstimate:
        if self.t % 2:
            return PoseEstimate.invalid()
        return PoseEstimate(0.0, 0.0, 0.0, (self.t + 1.0) * np.eye(3), True)


def test_the_replay_keeps_each_estimates_covariance(recordings: dict[str, Recording]) -> None:
    rec = recordings["soccer"]
    out = replay_into(Blinker(), rec, np.random.default_rng(0))
    assert out.covariances.shape == (rec.steps, 3, 3)
    steps = np.arange(rec.steps)
    np.testing.assert_array_equal(out.valid, steps % 2 == 0)
    np.testing.assert_array_equal(out.covariances[out.valid], (steps[out.valid] + 1.0)[:, None, None] * np.eye(3))
    assert np.isnan(out.covariances[~out.valid]).all()  # no pose, no covariance


def test_a_closed_loop_recording_keeps_the_online_estimate_and_its_replay_equals_it() -> None:
    """record_policy: a policy acting on the observation with the env's own localizer's estimate; that estimate
    is kept, and replaying the localizer with online_rng reproduces it bit for bit (on every stored sensor's leaves)."""
    from agents.experiments.replay import online_rng, record_policy, replay_into, start_prior
    from agents.experiments.scene_maps import AMCL_LIKE
    from agents.policies import make_policy
    from localizers.registry import make_localizer

    kwargs = {"crowd_size": 10, "localizer": "mcl_lidar", "localizer_params": AMCL_LIKE, "prior": "start"}
    rec = record_policy("crowdloc/StereoCampus-v0", lambda env: make_policy("route_follower", env, seed=3), 3, max_steps=60,
                        env_kwargs=kwargs)  # fmt: skip
    assert rec.steps == 61 and rec.estimates.shape == (61, 3) and np.isfinite(rec.estimates).all()
    assert set(rec.observations) == {"odometry", "lidar", "stereo"}  # the sensors only, not the wrapper's entries
    assert float(np.hypot(*(rec.true_pose[-1, :2] - rec.true_pose[0, :2]))) > 1.0  # it drove on the estimate
    loc = make_localizer("mcl_lidar", rec.localizer_map("scan"), dt_s=rec.dt_s, params=AMCL_LIKE)
    out = replay_into(loc, rec, online_rng(3), prior=start_prior(rec), measurement="scan")
    np.testing.assert_array_equal(out.estimates, rec.estimates)
    # without a localizer in the env there is no estimate to keep
    assert record("crowdloc/RoboCupStatic-v0", exp1_driver, seed=4, max_steps=3).estimates.shape == (0, 3)
