"""What the experiment reads from the world and the localizers' configs, in one place.

Every read of ``envs`` (the campus's world config) and of the shipped localizer configs
(``configs/localizers/*.yaml`` through :mod:`localizers.registry`) goes through this module,
so that the report states what the code ran with and a change of the env's interface touches
one file. Read here: ``load_world("stereo_campus")``: ``size_m``, ``dt_s``,
``max_episode_steps``, the robot's speed limit, its ``stereo_camera``, ``lidar`` and
``odometry`` sensors, its ``campus`` crowd (``count``, ``car_share``, ``group_share``,
``parked``), its ``route`` feature and its ``buildings``.
"""

from __future__ import annotations

import functools
from typing import Any

import numpy as np
from numpy.typing import NDArray

from agents.experiments.scene_maps import AMCL_LIKE
from envs.config import WorldConfig, load_world
from envs.features.route import RouteConfig
from envs.features.scenery import BuildingsConfig
from envs.sensors import LidarConfig
from envs.sensors.stereo_camera import StereoCameraConfig
from localizers.far_landmark_pf import FarLandmarkParams
from localizers.mcl_lidar import LidarMCLParams
from localizers.registry import load_params, params_path

WORLD = "stereo_campus"  # the world behind ``crowdloc/StereoCampus-v0``
LOCALIZER = "far_landmark_pf"  # the paper's method
REFERENCE = "mcl_lidar"  # the LIDAR reference (the paper's amcl), with :data:`agents.experiments.scene_maps.AMCL_LIKE`


@functools.cache
def campus() -> WorldConfig:
    """The campus's world config, as shipped."""
    return load_world(WORLD)


def _one(type_name: str) -> tuple[str, Any]:
    found = campus().sensors_of_type(type_name)
    if len(found) != 1:
        raise RuntimeError(f"world {WORLD!r} has {len(found)} {type_name} sensors, the experiment expects one")
    return next(iter(found.items()))


def camera_name() -> str:
    return _one("stereo_camera")[0]


def camera() -> StereoCameraConfig:
    config = _one("stereo_camera")[1]
    assert isinstance(config, StereoCameraConfig)
    return config


def lidar_name() -> str:
    return _one("lidar")[0]


def lidar() -> LidarConfig:
    config = _one("lidar")[1]
    assert isinstance(config, LidarConfig)
    return config


def default_crowd() -> int:
    """The world's crowd size (pedestrians and cars together)."""
    crowd = campus().crowd
    if crowd is None:
        raise RuntimeError(f"world {WORLD!r} has no crowd")
    return int(crowd.count)


def crowd_config() -> Any:
    """The campus crowd's config (``count``, ``car_share``, ``group_share``, ``parked``, ``max_count``)."""
    return campus().crowd


def cars_of(count: int) -> int:
    """Cars among ``count`` members: ``car_share`` of them rounded half up (``envs/crowds/campus/config.py``)."""
    return int(np.floor(count * float(crowd_config().car_share) + 0.5))


def route() -> NDArray[np.float64]:
    """``(P, 2)`` the route's points in driving order."""
    routes = campus().features_of_type("route")
    if len(routes) != 1:
        raise RuntimeError(f"world {WORLD!r} has {len(routes)} routes, the experiment expects one")
    feature = next(iter(routes.values()))
    assert isinstance(feature, RouteConfig)
    return np.asarray(feature.points_m, dtype=np.float64)


def route_arc() -> NDArray[np.float64]:
    """``(P,)`` the arc length of each route point."""
    r = route()
    return np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(r, axis=0).T))])


def route_length_m() -> float:
    return float(route_arc()[-1])


def turn_arc_m() -> tuple[float, float]:
    """Where the right turn begins and ends along the route (the first leg's end, the last leg's start)."""
    arc = route_arc()
    return float(arc[1]), float(arc[-2])


def buildings() -> list[tuple[str, NDArray[np.float64]]]:
    """``(name, (K, 2) footprint)`` of every building (for the maps of the figures)."""
    out = []
    for feature in campus().features_of_type("buildings").values():
        assert isinstance(feature, BuildingsConfig)
        for b in feature.items:
            out.append((str(b.name), np.asarray(b.footprint_m, dtype=np.float64)))
    return out


def far_landmark_defaults() -> FarLandmarkParams:
    """``far_landmark_pf``'s shipped parameters."""
    params = load_params(LOCALIZER)
    assert isinstance(params, FarLandmarkParams)
    return params


def reference_params() -> LidarMCLParams:
    """The reference's parameters: ``mcl_lidar``'s shipped ones with :data:`AMCL_LIKE` on top."""
    params = load_params(REFERENCE, AMCL_LIKE)
    assert isinstance(params, LidarMCLParams)
    return params


def params_file(name: str) -> str:
    """A localizer config's path in the checkout."""
    return f"configs/localizers/{params_path(name).name}"
