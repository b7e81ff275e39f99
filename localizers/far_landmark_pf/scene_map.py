"""The far-landmark paper's map (paper D, sec. 2.2): *scenes* recorded on a first drive.

A mapping drive records, at a fixed period, a scene: the robot's pose ``(x, y, theta)``, how
uncertain that pose was (its covariance: the LIDAR reference's own, zeros when the pose is the
truth), and the landmarks it observed, each as its edge type and its position ``(x, y)`` relative to that
pose (x forward, y left, metres). At localization time the scenes recorded near the current
estimate give the landmarks to match (:meth:`SceneMap.landmarks_near`).

A map knows what it was made for: the world's name and a fingerprint of its static geometry
(:func:`geometry_fingerprint` of the localizers' map, walls and bounds) and of the camera
whose edges it holds (``camera``: plain values of its metadata). A map whose world does not
match is refused, naming the mismatch (:meth:`SceneMap.check_world`). Files are ``.npz``
(:meth:`SceneMap.save`, :meth:`SceneMap.load`). This module imports nothing from ``envs``.
"""

from __future__ import annotations

import hashlib
import json
import math
import zipfile
import zlib
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from core.schema import ConfigError
from localizers.base import EDGE_TYPES, LandmarkMap
from localizers.range_table import write_atomically

Array = NDArray[np.float64]
IntArray = NDArray[np.int64]
FORMAT = "crowdloc-scene-map-v2"


def geometry_fingerprint(landmarks: LandmarkMap) -> str:
    """sha256 (hex, 16 characters) of the map's bounds and walls (with their heights): what a scene
    map's landmarks were measured against."""
    h = hashlib.sha256(FORMAT.encode())
    h.update(np.asarray(landmarks.bounds_m, dtype=np.float64).tobytes())
    h.update(np.ascontiguousarray(np.asarray(landmarks.walls_m, dtype=np.float64)).tobytes())
    if landmarks.wall_heights_m is not None:
        h.update(np.ascontiguousarray(np.asarray(landmarks.wall_heights_m, dtype=np.float64)).tobytes())
    return h.hexdigest()[:16]


@dataclass(frozen=True, eq=False)
class SceneMap:
    """Scenes of a mapping drive (module docstring).

    Attributes:
        poses: ``(S, 3)`` each scene's recorded pose.
        first: ``(S + 1,)`` scene ``s``'s landmarks are ``first[s]:first[s + 1]``.
        types: ``(L,)`` edge types; ``relative_xy``: ``(L, 2)`` positions relative to the scene's pose.
        world: the world's name; ``fingerprint``: :func:`geometry_fingerprint` of its map.
        camera: the camera's settings the edges depend on (plain values).
        pose_covariances: ``(S, 3, 3)`` each recorded pose's covariance (None: zeros, the poses
            are exact). A scene's landmarks inherit its pose's error, shared by all of them.
        source: how the poses were known (``"reference"``: a LIDAR localizer's estimate, as on
            a real robot; ``"truth"``), and what else describes the drive (plain values).
    """

    poses: Array
    first: IntArray
    types: IntArray
    relative_xy: Array
    world: str
    fingerprint: str
    camera: Mapping[str, Any] = field(default_factory=dict)
    source: Mapping[str, Any] = field(default_factory=dict)
    pose_covariances: Array | None = None

    def __post_init__(self) -> None:
        poses = np.asarray(self.poses, dtype=np.float64).reshape(-1, 3)
        first = np.asarray(self.first, dtype=np.int64).reshape(-1)
        types = np.asarray(self.types, dtype=np.int64).reshape(-1)
        rel = np.asarray(self.relative_xy, dtype=np.float64).reshape(-1, 2)
        if first.shape != (poses.shape[0] + 1,) or first[0] != 0 or np.any(np.diff(first) < 0) or first[-1] != types.size:
            raise ValueError(f"SceneMap: first must run from 0 to the landmark count {types.size} over {poses.shape[0]} scenes")
        if rel.shape[0] != types.size:
            raise ValueError(f"SceneMap: {types.size} types but {rel.shape[0]} positions")
        if not (np.isfinite(poses).all() and np.isfinite(rel).all()):
            raise ValueError("SceneMap: poses and positions must be finite")
        if types.size and (types.min() < 0 or types.max() >= EDGE_TYPES):
            raise ValueError(f"SceneMap: edge types must be in 0..{EDGE_TYPES - 1}, got {types.min()}..{types.max()}")
        covs = (
            np.zeros((poses.shape[0], 3, 3))
            if self.pose_covariances is None
            else np.asarray(self.pose_covariances, dtype=np.float64)
        )
        if covs.shape != (poses.shape[0], 3, 3):
            raise ValueError(f"SceneMap: pose_covariances must be ({poses.shape[0]}, 3, 3), one per scene, got {covs.shape}")
        if not np.isfinite(covs).all() or np.any(np.diagonal(covs, axis1=1, axis2=2) < 0.0):
            raise ValueError("SceneMap: pose_covariances must be finite with variances >= 0")
        for name, value in (("poses", poses), ("first", first), ("types", types), ("relative_xy", rel),
                            ("pose_covariances", covs)):  # fmt: skip
            value.setflags(write=False)
            object.__setattr__(self, name, value)

    @property
    def scene_count(self) -> int:
        return int(self.poses.shape[0])

    @property
    def landmark_count(self) -> int:
        return int(self.types.size)

    def pose_covariance(self, scenes: IntArray) -> Array:
        """``(3, 3)`` the mean covariance of ``scenes``' poses (zeros for none). The mean, not the
        covariance of an average: consecutive scenes' errors are those of one drifting estimate, so
        matching several scenes does not average their errors away."""
        if scenes.size == 0:
            return np.zeros((3, 3))
        return np.asarray(self._covariances()[scenes].mean(axis=0), dtype=np.float64)

    def _covariances(self) -> Array:
        """``pose_covariances`` as the array ``__post_init__`` made of it (None becomes zeros)."""
        covs = self.pose_covariances
        assert covs is not None  # __post_init__ replaced None
        return covs

    def world_xy(self, scene: int) -> Array:
        """``(K, 2)`` scene ``scene``'s landmarks in the world frame (its pose composed with them)."""
        x, y, th = self.poses[scene]
        rel = self.relative_xy[self.first[scene] : self.first[scene + 1]]
        c, s = math.cos(th), math.sin(th)
        return np.stack([x + c * rel[:, 0] - s * rel[:, 1], y + s * rel[:, 0] + c * rel[:, 1]], axis=1)

    def nearest_scenes(self, pose: ArrayLike, count: int, radius_m: float) -> IntArray:
        """Up to ``count`` scenes recorded within ``radius_m`` of ``pose`` (x, y), nearest first."""
        p = np.asarray(pose, dtype=np.float64)
        d = np.hypot(self.poses[:, 0] - p[0], self.poses[:, 1] - p[1])
        near = np.flatnonzero(d <= radius_m)
        return near[np.argsort(d[near], kind="stable")[:count]]

    def landmarks_near(self, pose: ArrayLike, count: int, radius_m: float) -> tuple[IntArray, Array, IntArray]:
        """The landmarks of :meth:`nearest_scenes` (:meth:`landmarks_of` them)."""
        return self.landmarks_of(self.nearest_scenes(pose, count, radius_m))

    def landmarks_of(self, scenes: IntArray) -> tuple[IntArray, Array, IntArray]:
        """The landmarks of ``scenes``, in the world frame, sorted by type: ``(types (M,), xy (M, 2),
        type_start (EDGE_TYPES + 1,))`` (type ``t``'s are ``type_start[t]:type_start[t + 1]``)."""
        if scenes.size == 0:
            return np.zeros(0, dtype=np.int64), np.zeros((0, 2)), np.zeros(EDGE_TYPES + 1, dtype=np.int64)
        types = np.concatenate([self.types[self.first[s] : self.first[s + 1]] for s in scenes])
        xy = np.concatenate([self.world_xy(int(s)) for s in scenes])
        order = np.argsort(types, kind="stable")
        types, xy = types[order], np.ascontiguousarray(xy[order])
        return types, xy, np.searchsorted(types, np.arange(EDGE_TYPES + 1)).astype(np.int64)

    # ------------------------------------------------------------------ files
    def save(self, path: str | Path) -> Path:
        """Write the map to ``path`` (``.npz``); returns the path.

        Written atomically (:func:`localizers.range_table.write_atomically`: a temporary file in
        the same folder, then renamed): a killed or concurrent first build never leaves a
        truncated map behind."""
        meta = {"format": FORMAT, "world": self.world, "fingerprint": self.fingerprint, "camera": dict(self.camera),
                "source": dict(self.source)}  # fmt: skip

        def write(tmp: Path) -> None:
            with tmp.open("wb") as f:
                np.savez_compressed(f, poses=self.poses, first=self.first, types=self.types, relative_xy=self.relative_xy,
                                    pose_covariances=self._covariances(), meta=np.array(json.dumps(meta, sort_keys=True)))  # fmt: skip

        return write_atomically(Path(path), write)

    @staticmethod
    def load(path: str | Path) -> SceneMap:
        """Read a map written by :meth:`save`.

        Raises:
            ConfigError: naming the file when it is missing, not a scene map or unreadable (a
                truncated or corrupt file: remove it and make it again).
        """
        src = Path(path)
        if not src.is_file():
            raise ConfigError(f"scene map {str(src)!r} does not exist (make one with `crowdloc map WORLD`)")
        try:
            with src.open("rb") as fh, np.load(fh, allow_pickle=False) as data:  # the file is closed if it is no zip
                meta = json.loads(str(data["meta"]))
                if meta.get("format") != FORMAT:
                    raise ConfigError(
                        f"{str(src)!r} is not a scene map of format {FORMAT!r} (found {meta.get('format')!r}): make it again "
                        "with `crowdloc map WORLD`"
                    )
                arrays = {k: data[k] for k in ("poses", "first", "types", "relative_xy", "pose_covariances")}
        except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile, zlib.error) as exc:
            raise ConfigError(
                f"{str(src)!r} is not a scene map or cannot be read ({type(exc).__name__}: {exc}); a truncated or corrupt "
                "file: remove it and make it again (`crowdloc map WORLD`; a world's default map in the cache is made again on "
                "next use)"
            ) from None
        return SceneMap(
            **arrays, world=meta["world"], fingerprint=meta["fingerprint"], camera=meta["camera"], source=meta["source"]
        )

    def check_world(self, landmarks: LandmarkMap, world: str | None = None, camera: Mapping[str, Any] | None = None) -> None:
        """Raise :class:`ConfigError` unless the map was made in this world (and with this camera),
        naming what differs."""
        if world is not None and world != self.world:
            raise ConfigError(f"the scene map was made in world {self.world!r}, not {world!r}")
        mine = geometry_fingerprint(landmarks)
        if mine != self.fingerprint:
            raise ConfigError(
                f"the scene map of world {self.world!r} was made against another geometry (fingerprint {self.fingerprint}, "
                f"this map's {mine}): the world's walls, buildings or bounds changed; make the map again"
            )
        if camera is not None:
            camera = json.loads(json.dumps(dict(camera), sort_keys=True))  # the values as the file holds them
            differ = {k: (self.camera.get(k), v) for k, v in camera.items() if self.camera.get(k) != v}
            if differ:
                pairs = ", ".join(f"{k}: map {a!r}, camera {b!r}" for k, (a, b) in sorted(differ.items()))
                raise ConfigError(f"the scene map's edges come from another camera ({pairs}); make the map again")
