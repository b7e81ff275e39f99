"""LocalizationObservation: every bearing localizer through gym.make, spaces, truth kept out, seeding."""

from __future__ import annotations

import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from stable_baselines3.common.env_checker import check_env as sb3_check_env

import envs  # noqa: F401
from core.schema import ConfigError
from envs.wrappers import LocalizationObservation, bearing_measurement, hypothesis_spread
from localizers.base import Overlay, PoseEstimate
from localizers.registry import LOCALIZERS
from tests.envs.exact import EXACT

BEARING_LOCALIZERS = sorted(name for name, s in LOCALIZERS.items() if s.measurement == "bearings")
SOCCER_IDS = ["crowdloc/RoboCupStatic-v0", "crowdloc/RoboCupCrowded-v0"]


def rollout(env: gym.Env, seed: int, steps: int) -> list[tuple[dict, dict]]:
    obs, info = env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    out = [(obs, info)]
    for _ in range(steps):
        obs, _, terminated, truncated, info = env.step(rng.uniform(-1, 1, 2).astype(np.float32))
        out.append((obs, info))
        if terminated or truncated:
            break
    return out


@pytest.mark.parametrize("name", BEARING_LOCALIZERS)
@pytest.mark.parametrize("env_id", SOCCER_IDS)
def test_every_bearing_localizer_runs_through_gym_make(env_id: str, name: str) -> None:
    env = gym.make(env_id, localizer=name)
    for obs, info in rollout(env, seed=3, steps=150):
        assert env.observation_space.contains(obs), {k: v for k, v in obs.items() if not env.observation_space[k].contains(v)}
        assert isinstance(info["estimate"], PoseEstimate)
        valid = bool(obs["estimate_valid"][0])
        assert valid == info["estimate"].valid
        if not valid:
            assert not obs["estimate"].any()
    env.close()


@pytest.mark.parametrize("name", ["candidate_sets", "mcl_bearing", "kalman"])
def test_wrapped_env_passes_the_checkers(name: str) -> None:
    env = gym.make("crowdloc/RoboCupCrowded-v0").unwrapped
    wrapped = LocalizationObservation(env, name)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(wrapped, skip_render_check=True)
    # gymnasium always notes that a wrapped env differs from its unwrapped one; nothing else may warn
    assert [str(w.message) for w in caught if "unwrapped version" not in str(w.message)] == []
    assert len(caught) == 1
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        sb3_check_env(wrapped, warn=True, skip_render_check=True)


@pytest.mark.parametrize("name", BEARING_LOCALIZERS)
def test_the_estimate_is_reported_in_world_units_and_normalized_in_the_observation(name: str) -> None:
    env = gym.make("crowdloc/RoboCupCrowded-v0", localizer=name, crowd_size=0)
    fixes = 0
    for obs, info in rollout(env, seed=1, steps=200):
        est = info["estimate"]
        if not est.valid:
            continue
        fixes += 1
        x, y = np.clip([(est.x_m - 2.5) / 2.5, (est.y_m - 2.5) / 2.5], -1, 1)
        np.testing.assert_allclose(obs["estimate"], [x, y, np.cos(est.theta_rad), np.sin(est.theta_rad)], atol=1e-6)
    assert fixes > 100, f"{name} gave a pose on only {fixes} of 200 steps with all 8 landmarks in view"
    env.close()


@pytest.mark.parametrize("name", BEARING_LOCALIZERS)
def test_no_observation_leaf_holds_the_true_pose(name: str) -> None:
    env = gym.make("crowdloc/RoboCupCrowded-v0", localizer=name, belief_spread=True)  # every optional key too
    assert "belief_spread" in env.observation_space.spaces
    for obs, info in rollout(env, seed=5, steps=100):
        truth = np.asarray(info["true_pose"])
        for key, leaf in obs.items():
            assert "true" not in key and "pose" not in key
            assert not np.any(np.isclose(np.asarray(leaf, dtype=np.float64).reshape(-1, 1), truth[None, :], atol=1e-6, rtol=0)), (
                key
            )
    env.close()


def test_filtering_never_changes_the_world() -> None:
    plain = rollout(gym.make("crowdloc/RoboCupCrowded-v0"), seed=9, steps=200)
    filtered = rollout(gym.make("crowdloc/RoboCupCrowded-v0", localizer="mcl_bearing"), seed=9, steps=200)
    for (obs_a, info_a), (obs_b, info_b) in zip(plain, filtered):
        np.testing.assert_array_equal(info_a["true_pose"], info_b["true_pose"])
        np.testing.assert_array_equal(obs_a["landmarks"], obs_b["landmarks"])
        np.testing.assert_array_equal(obs_a["odometry"], obs_b["odometry"])


@pytest.mark.parametrize("name", ["mcl_bearing", "mcl_bearing_paper", "candidate_sets"])
def test_same_seed_same_estimates_and_reset_mid_episode_starts_over(name: str) -> None:
    env_a = gym.make("crowdloc/RoboCupCrowded-v0", localizer=name)
    env_b = gym.make("crowdloc/RoboCupCrowded-v0", localizer=name)
    run_a = rollout(env_a, seed=4, steps=120)
    run_b = rollout(env_b, seed=4, steps=120)
    for (oa, _), (ob, _) in zip(run_a, run_b):
        for key in oa:
            np.testing.assert_array_equal(oa[key], ob[key])
    # a reset in the middle of an episode replays the episode from the start
    again = rollout(env_a, seed=4, steps=120)
    for (oa, _), (ob, _) in zip(run_a, again):
        np.testing.assert_array_equal(oa["estimate"], ob["estimate"])


def test_prior_start_gives_dead_reckoning_the_true_start_pose() -> None:
    env = gym.make(
        "crowdloc/RoboCupCrowded-v0",
        localizer="dead_reckoning",
        odometry={"alpha1": 0.0, "alpha2": 0.0, "alpha3": 0.0, "alpha4": 0.0, **EXACT},
        crowd_size=0,
    )
    obs, info = env.reset(seed=2)
    est = info["estimate"]
    np.testing.assert_allclose([est.x_m, est.y_m, est.theta_rad], info["true_pose"], atol=1e-9)
    for _ in range(30):
        obs, _, _, _, info = env.step(np.array([0.5, 0.2], dtype=np.float32))
    est = info["estimate"]
    # float32 odometry: drift of micrometres only
    np.testing.assert_allclose([est.x_m, est.y_m], info["true_pose"][:2], atol=1e-4)


def test_bearing_measurement_reads_the_flat_camera_slots() -> None:
    slots = np.zeros(9, dtype=np.float32)
    slots[3:6] = (1.0, np.cos(0.5), np.sin(0.5))
    slots[6:9] = (1.0, np.cos(-2.0), np.sin(-2.0))
    m = bearing_measurement(slots)
    np.testing.assert_array_equal(m.landmark_ids, [1, 2])
    np.testing.assert_allclose(m.bearings_rad, [0.5, -2.0], atol=1e-6)


@pytest.mark.parametrize(
    ("kwargs", "needle"),
    [
        ({"localizer": "kalmann"}, "kalmann"),
        ({"localizer": "candidate_sets", "localizer_params": {"max_setz": 3}}, "max_setz"),
        ({"localizer": "candidate_sets", "prior": "sometimes"}, "sometimes"),
        ({"localizer": "candidate_sets", "belief_spread": "yes"}, "'yes'"),
    ],
)
def test_bad_localizer_arguments_name_the_bad_value(kwargs: dict, needle: str) -> None:
    with pytest.raises(ConfigError, match=needle):
        gym.make("crowdloc/RoboCupCrowded-v0", **kwargs)


def test_localizer_params_without_a_localizer_is_an_error() -> None:
    with pytest.raises(ValueError, match="localizer"):
        gym.make("crowdloc/RoboCupCrowded-v0", localizer_params={"max_sets": 3})
    with pytest.raises(ValueError, match="belief_spread"):
        gym.make("crowdloc/RoboCupCrowded-v0", belief_spread=True)


def test_hypothesis_spread_is_the_weighted_position_and_circular_heading_spread() -> None:
    poses = np.array([[0.0, 0.0, 0.3], [2.0, 0.0, -0.3], [5.0, 5.0, 3.0]])
    # the third hypothesis has no weight: two points 2 m apart spread 1 m around their mean
    position, heading = hypothesis_spread(Overlay(poses=poses, weights=np.array([1.0, 1.0, 0.0])))
    assert position == pytest.approx(1.0)
    assert heading == pytest.approx(np.sqrt(-2.0 * np.log(np.cos(0.3))))
    position, heading = hypothesis_spread(Overlay(poses=poses[:1], weights=np.ones(1)))
    assert position == 0.0 and heading == pytest.approx(0.0, abs=1e-7)
    # opposite headings cancel: the circular spread is unbounded (larger than pi, up to rounding)
    _, heading = hypothesis_spread(Overlay(poses=np.array([[0.0, 0.0, 0.0], [0.0, 0.0, np.pi]]), weights=np.ones(2)))
    assert heading > np.pi
    assert np.isnan(hypothesis_spread(Overlay())).all()
    assert np.isnan(hypothesis_spread(Overlay(poses=poses, weights=np.zeros(3)))).all()


def test_the_candidate_sets_own_hypothesis_spread_equals_the_generic_one() -> None:
    env = gym.make("crowdloc/RoboCupCrowded-v0", localizer="candidate_sets", prior="none", camera={"fov_rad": np.pi / 2})
    localizer = env.get_wrapper_attr("localizer")
    env.reset(seed=11)
    rng = np.random.default_rng(11)
    compared = 0
    for _ in range(200):
        env.step(np.array([rng.uniform(-1, 1), 1.0], dtype=np.float32))  # turning: landmarks come into view
        generic = hypothesis_spread(localizer.overlay())
        if np.isfinite(generic[0]):
            compared += 1
        np.testing.assert_allclose(localizer.hypothesis_spread(), generic, rtol=1e-9, atol=1e-9)
    assert compared > 100


@pytest.mark.parametrize("name", ["candidate_sets", "mcl_bearing", "kalman"])
def test_belief_spread_is_observed_only_when_asked_and_shows_the_hypotheses_before_a_fix(name: str) -> None:
    kwargs = {"localizer": name, "prior": "none", "camera": {"fov_rad": np.pi / 2}}
    plain = gym.make("crowdloc/RoboCupCrowded-v0", **kwargs)
    env = gym.make("crowdloc/RoboCupCrowded-v0", belief_spread=True, **kwargs)
    assert "belief_spread" not in plain.observation_space.spaces
    assert env.observation_space["belief_spread"].shape == (2,)
    base = env.unwrapped
    diag = np.hypot(*np.subtract(base.landmark_map.bounds_m[2:], base.landmark_map.bounds_m[:2]))
    localizer = env.get_wrapper_attr("localizer")
    obs, info = env.reset(seed=6)
    plain_obs, _ = plain.reset(seed=6)
    rng = np.random.default_rng(6)
    before_fix = []
    for _ in range(150):
        assert env.observation_space.contains(obs)
        for key, leaf in plain_obs.items():  # the option only adds a key
            np.testing.assert_array_equal(obs[key], leaf)
        position, heading = hypothesis_spread(localizer.overlay())  # the definition, whatever route the wrapper takes
        if np.isfinite(position):
            np.testing.assert_allclose(obs["belief_spread"], [min(position / diag, 1), min(heading / np.pi, 1)], rtol=1e-6)
        else:  # no hypotheses: the estimate's own spread
            np.testing.assert_array_equal(obs["belief_spread"], obs["estimate_spread"])
        if not info["estimate"].valid:
            before_fix.append(obs["belief_spread"])
        action = rng.uniform(-1, 1, 2).astype(np.float32)
        obs, _, _, _, info = env.step(action)
        plain_obs, *_ = plain.step(action)
    if name != "kalman":  # the Kalman filter has no hypotheses and no pose without a prior
        assert before_fix and np.min(before_fix) < 0.5, f"{name}: the hypotheses never narrowed before a fix"


def test_a_bearing_localizer_on_a_lidar_world_is_refused() -> None:
    with pytest.raises(ConfigError, match="needs a bearing_camera sensor"):
        gym.make("crowdloc/CrowdedRoom-v0", localizer="candidate_sets")


class _ExtraKey(gym.ObservationWrapper):
    """Adds one constant observation entry ``key`` (to collide with the localizer wrapper's)."""

    def __init__(self, env: gym.Env, key: str) -> None:
        super().__init__(env)
        self.key = key
        self.observation_space = gym.spaces.Dict({**env.observation_space.spaces, key: gym.spaces.Box(0.0, 1.0, (1,))})

    def observation(self, observation: dict) -> dict:
        return {**observation, self.key: np.zeros(1, dtype=np.float32)}


@pytest.mark.parametrize("key", ["estimate", "estimate_valid", "estimate_spread", "belief_spread"])
def test_a_key_the_wrapper_adds_may_not_be_in_the_env_already(key: str) -> None:
    env = _ExtraKey(gym.make("crowdloc/RoboCupCrowded-v0"), key)
    with pytest.raises(ConfigError, match=rf"adds the observation key '{key}', which the env already has"):
        LocalizationObservation(env, "candidate_sets", belief_spread=True)
    if key == "belief_spread":  # only a wrapper that adds it refuses it
        LocalizationObservation(env, "candidate_sets", belief_spread=False)


def test_a_sensor_can_carry_the_bearings_under_another_key() -> None:
    # the wrapper finds the camera by its type, not by the observation key
    moved = gym.make("crowdloc/RoboCupCrowded-v0", localizer="candidate_sets", camera={"key": "bearings_seen"})
    usual = gym.make("crowdloc/RoboCupCrowded-v0", localizer="candidate_sets")
    a, _ = moved.reset(seed=0)
    b, _ = usual.reset(seed=0)
    assert "landmarks" not in a and a["bearings_seen"].shape == (24,)
    for _ in range(20):
        np.testing.assert_array_equal(a["estimate"], b["estimate"])
        np.testing.assert_array_equal(a["bearings_seen"], b["landmarks"])
        a, *_ = moved.step(np.array([0.5, 0.3], dtype=np.float32))
        b, *_ = usual.step(np.array([0.5, 0.3], dtype=np.float32))
    assert b["estimate_valid"][0] == 1.0


# --- observations of the wrong shape (a named error, not numpy's reshape or IndexError, nor 27 values accepted) ---


class _Cut(gym.ObservationWrapper):
    """Hands the localizer wrapper one observation key with ``values`` in place of the sensor's."""

    def __init__(self, env: gym.Env, key: str, values: np.ndarray) -> None:
        super().__init__(env)
        self.key, self.values = key, values

    def observation(self, observation: dict) -> dict:
        return {**observation, self.key: self.values}


@pytest.mark.parametrize(
    ("env_id", "localizer", "key", "values", "expected"),
    [
        ("crowdloc/RoboCupCrowded-v0", "candidate_sets", "landmarks", np.ones(5, np.float32), r"\(24,\), got \(5,\)"),
        ("crowdloc/RoboCupCrowded-v0", "candidate_sets", "landmarks", np.zeros(27, np.float32), r"\(24,\), got \(27,\)"),
        ("crowdloc/RoboCupCrowded-v0", "dead_reckoning", "odometry", np.zeros(2, np.float32), r"\(3,\), got \(2,\)"),
        ("crowdloc/CrowdedRoom-v0", "mcl_lidar", "lidar", np.ones(1080, np.float32), r"\(1081,\), got \(1080,\)"),
    ],
)
def test_an_observation_of_the_wrong_shape_is_refused_naming_its_key_and_both_shapes(
    env_id: str, localizer: str, key: str, values: np.ndarray, expected: str
) -> None:
    from localizers.base import MeasurementError

    base = gym.make(env_id).unwrapped
    env = LocalizationObservation(_Cut(base, key, values), localizer, {"n_particles": 20} if "mcl" in localizer else None)
    with pytest.raises(MeasurementError, match=rf"observation '{key}' \(.*\): expected shape {expected}"):
        env.reset(seed=0)
        env.step(np.zeros(2, np.float32))


def test_the_decoders_check_the_metadata_shapes() -> None:
    from localizers.base import MeasurementError
    from localizers.measurements import edge_measurement, odometry_delta

    with pytest.raises(
        MeasurementError, match=r"observation 'stereo' \(stereo edge slots.*\): expected shape \(384,\), got \(8,\)"
    ):
        edge_measurement(np.zeros(8), {"key": "stereo", "slots": 96})
    with pytest.raises(MeasurementError, match=r"expected shape \(n,\) with n a multiple of 4, got \(6,\)"):
        edge_measurement(np.zeros(6))  # no metadata: whole slots
    with pytest.raises(MeasurementError, match=r"expected shape \(n,\) with n a multiple of 3, got \(5,\)"):
        bearing_measurement(np.zeros(5))
    assert odometry_delta(np.array([0.1, 0.0, 0.2], np.float32)).dtheta_rad == pytest.approx(0.2)
