"""Scene maps for ``far_landmark_pf``: the far-landmark paper's first drive (run 1), and the default map.

The paper drives its route once to make the map: at a fixed period a *scene* records the
robot's pose and the landmarks its stereo camera sees (edge type, position relative to the
robot). Here :func:`build_scene_map` drives a world's route with ``route_follower`` on the
LIDAR reference's estimate (``mcl_lidar`` in ROS amcl's likelihood-field configuration,
:data:`AMCL_LIKE`, on the world's 360 deg LIDAR: the paper's amcl on a flattened VLP-16) and
records every ``period_s``: the pose is that reference's estimate (``pose="reference"``, the
default, as on a real robot) or the truth (``pose="truth"``); the landmarks are the camera's
detections of that step. On free-running webcams the drive takes its bends slowly and a scene due
while it turns waits for the next frame (:attr:`MappingDrive.max_shift_px`): a frame taken
mid-turn has its far landmarks' ranges off, and a map made of such frames contradicts the right pose.

:func:`default_scene_map` is the world's default map: made once (seed 0, the crowd size of the
world's file, whatever crowd the env asking for it runs: the map comes from a normal day's drive,
and every env of the world gets the same one) and cached under ``$CROWDLOC_CACHE/scene_maps``
(default ``~/.cache/crowdloc``), keyed by the world's geometry and camera and by everything the drive depends
on (:func:`drive_fingerprint`: the world's whole config, its crowds' behaviour, LIDAR sweep and camera timing
included, the drive's settings and :data:`DRIVE_VERSION`), so ``gym.make(id, localizer="far_landmark_pf")``
works without a map file (:func:`prepare_far_landmark_pf`, the localizer's preparation hook) and never uses a
map that a drive in other conditions recorded.
``crowdloc map WORLD`` makes one explicitly.
"""

from __future__ import annotations

import hashlib
import json
import logging
import math
import os
from collections.abc import Mapping
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np
from tqdm import tqdm

from core.schema import ConfigError, check, is_real
from envs.config import WorldConfig
from envs.localization_env import LocalizationEnv, apply_overrides
from localizers.far_landmark_pf.scene_map import SceneMap, geometry_fingerprint
from localizers.mcl_lidar import LARGE_MAP_PARAMS
from localizers.measurements import edge_measurement, find_sensor, sensor_map
from localizers.range_table import cache_dir

_log = logging.getLogger(__name__)

#: the LIDAR reference: mcl_lidar as ROS amcl runs it (likelihood field, amcl's 1.0 sampling,
#: no recovery or lost test: injection drawn over a campus almost never lands near the robot, and
#: a lost test that fires when people pass would stop a robot that drives on the estimate)
AMCL_LIKE: dict[str, Any] = dict(LARGE_MAP_PARAMS)  # mcl_lidar's own defaults for a world too large for its beam model
#: the mapping drive's version: bump it when a change of the code (route_follower, the reference, the crowds)
#: changes what a drive in the same config records, so that cached default maps are made again
#: (2: the cache key holds the drive's conditions; maps cached before could come from a world's older defaults;
#: 3: no scene from a frame taken mid-turn, ``MappingDrive.max_shift_px``)
DRIVE_VERSION = 3
#: what of the stereo camera's metadata a map's edges depend on (a map made with another is refused)
CAMERA_KEYS = (
    "width_px",
    "height_px",
    "focal_px",
    "cx_px",
    "cy_px",
    "baseline_m",
    "forward_m",
    "height_m",
    "rows_px",
    "threshold",
)


@dataclass(frozen=True)
class MappingDrive:
    """How run 1 is driven and recorded.

    Attributes:
        seed: the env's seed (the crowd's).
        crowd_size: the crowd (None: the world's).
        pose: the scenes' poses: ``"reference"`` (the LIDAR reference's estimate) or ``"truth"``.
        period_s: a scene every this many seconds (1 s: about one per metre at the robot's 1 m/s).
        max_steps: stop after this many steps (None: the world's episode length).
        max_shift_px: a scene is recorded only from a frame whose cameras the robot's turn (the step's
            odometry) moved by at most this many pixels between their frames (turn rate x the rig's
            ``frame_gap_s`` x focal length); a scene due mid-turn waits for the first frame after it
            (ours: free-running webcams take their frames up to 1/30 s apart, so a frame taken
            in a turn has its disparities off by that shift, about 6 px at the campus corner's 0.33 rad/s,
            and its far landmarks' ranges with them; 1 px is about twice the rig's disparity noise). The drive turns
            no faster than that (``route_follower``'s ``max_turn``: it slows in bends, the campus corner at
            0.054 rad/s), so the scenes cover the bends' views too. Synchronised cameras (``frame_gap_s`` 0)
            neither slow in bends nor wait: every scene is recorded when due.
    """

    seed: int = 0
    crowd_size: int | None = None
    pose: Literal["reference", "truth"] = "reference"
    period_s: float = 1.0
    max_steps: int | None = None
    max_shift_px: float = 1.0

    def __post_init__(self) -> None:
        check(self.pose in ("reference", "truth"), f"mapping drive: pose must be 'reference' or 'truth', got {self.pose!r}")
        check(math.isfinite(self.period_s) and self.period_s > 0, f"mapping drive: period_s must be > 0, got {self.period_s!r}")
        check(
            is_real(self.max_shift_px) and self.max_shift_px > 0,
            f"mapping drive: max_shift_px must be a number > 0 (pixels), got {self.max_shift_px!r}",
        )


def reference_env_kwargs(config: WorldConfig) -> dict[str, Any]:
    """``gym.make`` keywords that run the LIDAR reference online from the start pose: ``mcl_lidar``
    with :data:`AMCL_LIKE` on the world's one LIDAR (what a route drive steers on).

    Raises:
        ConfigError: a world without exactly one LIDAR.
    """
    lidars = list(config.sensors_of_type("lidar"))
    if len(lidars) != 1:
        raise ConfigError(f"the LIDAR reference needs one LIDAR: world {config.name!r} has {len(lidars)}")
    return {"localizer": "mcl_lidar", "localizer_params": dict(AMCL_LIKE), "prior": "start", "localizer_sensor": lidars[0]}


def _camera(env: LocalizationEnv) -> tuple[str, dict[str, Any]]:
    found = [name for name, meta in env.sensor_metadata.items() if meta["type"] == "stereo_camera"]
    if len(found) != 1:
        raise ConfigError(f"a scene map needs one stereo camera; world {env.config.name!r} has {len(found)}")
    return found[0], env.sensor_metadata[found[0]]


def rig_timing(metadata: Mapping[str, Any]) -> dict[str, float]:
    """``far_landmark_pf``'s ``frame_gap_s`` and ``baseline_m`` from a stereo camera's metadata: what a turn can
    shift between the rig's frames, which its lost test allows for."""
    return {"frame_gap_s": float(metadata["frame_gap_s"]), "baseline_m": float(metadata["baseline_m"])}


def camera_signature(metadata: Mapping[str, Any]) -> dict[str, Any]:
    """The settings of a stereo camera's metadata that its edges depend on (:data:`CAMERA_KEYS`)."""
    return {key: metadata[key] for key in CAMERA_KEYS}


def world_fingerprint(env: LocalizationEnv) -> str:
    """The geometry fingerprint of the map the localizer gets (cut at the camera's height, as the wrapper cuts it)."""
    _, meta = _camera(env)
    return geometry_fingerprint(sensor_map(env.landmark_map, meta))


def build_scene_map(
    world: str | WorldConfig, drive: MappingDrive = MappingDrive(), env_kwargs: Mapping[str, Any] | None = None,
    progress: bool = False,
) -> SceneMap:  # fmt: skip
    """Drive ``world``'s route once and record its scenes (module docstring).

    Raises:
        ConfigError: a world without a route, a stereo camera or (for the reference) a LIDAR.
    """
    from agents.policies import make_policy
    from envs.wrappers import LocalizationObservation

    kwargs = dict(env_kwargs or {})
    if drive.crowd_size is not None:
        kwargs["crowd_size"] = drive.crowd_size
    base = LocalizationEnv(world, **kwargs)
    if not base.config.features_of_type("route"):
        raise ConfigError(f"a scene map is made by driving a route: world {base.config.name!r} has none")
    reference = reference_env_kwargs(base.config)
    camera, meta = _camera(base)
    key = str(meta["key"])
    env = LocalizationObservation(base, reference["localizer"], reference["localizer_params"], prior=reference["prior"],
                                  sensor=reference["localizer_sensor"])  # fmt: skip
    # the turn rate (rad/s) above which a frame's cameras moved more than max_shift_px between their frames
    max_turn_rps = (
        drive.max_shift_px / (float(meta["frame_gap_s"]) * float(meta["focal_px"])) if meta["frame_gap_s"] else math.inf
    )
    policy = make_policy("route_follower", env, seed=drive.seed,
                         max_turn=min(1.0, max_turn_rps / base.config.robot.max_turn_rate_rps))  # fmt: skip
    obs, info = env.reset(seed=drive.seed)
    every = max(1, round(drive.period_s / base.config.dt_s))
    limit = drive.max_steps or base.config.max_episode_steps
    odometry = str(base.sensor_metadata[find_sensor("odometry", base.sensor_metadata, "a mapping drive")]["key"])
    due = False  # a scene is due and waits for a frame taken out of a turn
    poses: list[np.ndarray] = []
    covariances: list[np.ndarray] = []
    types: list[np.ndarray] = []
    rel: list[np.ndarray] = []
    bar = tqdm(total=limit, desc=f"mapping {base.config.name}", unit="step", disable=not progress, leave=False)
    for step in range(limit):
        due = due or step % every == 0
        turn_rps = abs(float(obs[odometry][2])) / base.config.dt_s  # the step in which this frame was taken
        if due and turn_rps <= max_turn_rps:
            due = False
            est = info["estimate"]
            pose = np.asarray(info["true_pose"], dtype=np.float64) if drive.pose == "truth" else est.as_array()
            if np.all(np.isfinite(pose)) and (drive.pose == "truth" or est.valid):
                seen = edge_measurement(obs[key])
                r = 1.0 / seen.inverse_range_m
                poses.append(pose)
                covariances.append(np.zeros((3, 3)) if drive.pose == "truth" else np.asarray(est.covariance, dtype=np.float64))
                types.append(seen.types)
                rel.append(np.stack([r * np.cos(seen.bearings_rad), r * np.sin(seen.bearings_rad)], axis=1))
        action, _ = policy.predict(obs)
        obs, _, terminated, truncated, info = env.step(action)
        bar.update()
        if terminated or truncated:
            break
    bar.close()
    env.close()
    counts = [t.size for t in types]
    return SceneMap(
        np.asarray(poses, dtype=np.float64).reshape(-1, 3),
        np.concatenate([[0], np.cumsum(counts)]).astype(np.int64),
        np.concatenate(types) if types else np.zeros(0, dtype=np.int64),
        np.concatenate(rel) if rel else np.zeros((0, 2)),
        world=base.config.name,
        fingerprint=geometry_fingerprint(sensor_map(base.landmark_map, meta)),
        camera=json.loads(json.dumps(camera_signature(meta))),
        source={
            **asdict(drive),
            "camera": camera,
            "steps": step + 1,
            "reference": "mcl_lidar" if drive.pose == "reference" else None,
        },
        pose_covariances=np.asarray(covariances, dtype=np.float64).reshape(-1, 3, 3),
    )


def _short_hash(value: Any) -> str:
    """sha256 (hex, 8 characters) of ``value``'s JSON with sorted keys: a part of a cached map's name."""
    return hashlib.sha256(json.dumps(value, sort_keys=True).encode()).hexdigest()[:8]


def drive_fingerprint(config: WorldConfig, drive: MappingDrive) -> str:
    """:func:`_short_hash` of what a mapping drive records depends on besides the geometry: the
    world's whole config (the crowd the drive meets and how it behaves, the LIDAR the reference reads, the
    camera's timing), the drive's settings and :data:`DRIVE_VERSION`."""
    return _short_hash({"world": asdict(config), "drive": asdict(drive), "version": DRIVE_VERSION})


def default_drive(env: LocalizationEnv) -> tuple[WorldConfig, MappingDrive]:
    """The world config and drive of ``env``'s default map: its conditions at the crowd of the world's file."""
    drive = MappingDrive(crowd_size=env.file_crowd_size)
    return apply_overrides(env.config, crowd_size=drive.crowd_size), drive


def default_map_path(env: LocalizationEnv) -> Path:
    """Where the world's default scene map is cached: named by the world, its geometry, camera and drive
    (:func:`drive_fingerprint`; a world whose crowd, LIDAR or camera timing changed gets a new map). A seeded
    layout's map goes to the ``layouts`` folder beside them, which keeps the :data:`LAYOUT_MAPS_KEPT` last used."""
    _, meta = _camera(env)
    camera, conditions = _short_hash(camera_signature(meta)), drive_fingerprint(*default_drive(env))
    folder = cache_dir() / "scene_maps" / ("layouts" if env.layout is not None else "")
    return folder / f"{env.config.name}-{world_fingerprint(env)}-{camera}-{conditions}.npz"


#: how many seeded layouts' scene maps the cache keeps (about 100 KB each): the least recently used go first
LAYOUT_MAPS_KEPT = 256


def _keep_recent(folder: Path, keep: int) -> None:
    """Delete all but the ``keep`` most recently used scene maps in ``folder`` (a layout map cache: every
    ``.npz`` in it was written by :func:`default_scene_map`)."""
    maps = sorted(folder.glob("*.npz"), key=lambda p: p.stat().st_mtime if p.exists() else 0.0, reverse=True)
    for old in maps[keep:]:
        old.unlink(missing_ok=True)


def default_scene_map(env: LocalizationEnv) -> Path:
    """The world's default scene map (seed 0, the crowd size of the world's file), made and cached on first use,
    and made again (saying so) when the cached file cannot be read (left truncated by a writer of an older version).
    A seeded layout's map is made by its own drive (the layout's world, the same conditions) and cached among
    the layouts' maps, of which the :data:`LAYOUT_MAPS_KEPT` last used stay."""
    path = default_map_path(env)
    if path.is_file():
        try:
            SceneMap.load(path)
        except ConfigError as exc:
            _log.warning("the cached default scene map cannot be read, making it again: %s", exc)
            path.unlink(missing_ok=True)
    if not path.is_file():
        if env.layout is None:
            _log.warning("making the default scene map of %s (the route driven once; cached in %s)", env.config.name, path)
        build_scene_map(*default_drive(env), progress=env.layout is None).save(path)
    if env.layout is not None:
        os.utime(path)  # used now: the cache keeps the last used
        _keep_recent(path.parent, LAYOUT_MAPS_KEPT)
    return path


def prepare_far_landmark_pf(env: LocalizationEnv, sensor: str, params: Mapping[str, Any] | None) -> dict[str, Any]:
    """``far_landmark_pf``'s preparation (its registry entry names it): without a ``scene_map``
    in ``params``, the world's default (:func:`default_scene_map`); the map's camera must be this one's.
    ``frame_gap_s`` and ``baseline_m`` (what a turn can shift between the rig's frames) come from the
    camera's metadata unless ``params`` gives them."""
    out = {**rig_timing(env.sensor_metadata[sensor]), **(params or {})}
    if not out.get("scene_map"):
        out["scene_map"] = str(default_scene_map(env))
    scenes = SceneMap.load(out["scene_map"])
    scenes.check_world(sensor_map(env.landmark_map, env.sensor_metadata[sensor]), env.config.name,
                       camera_signature(env.sensor_metadata[sensor]))  # fmt: skip
    return out
