"""What the experiment reads from the world and the localizers, in one place.

Every read of ``envs`` (the world config and the live env's internals) and of the shipped
localizer configs (``configs/localizers/*.yaml`` through :mod:`localizers.registry`) goes
through this module, so that the report states what the code ran with and a change of the
env's interface touches one file. The env internals read here:

- ``env.world.positions[env.world.member_rows]``: the people's positions at a step (Fig. 5);
- ``load_world("crowded_room")``: ``size_m``, ``dt_s``, ``robot.radius_m`` / ``mass_kg``,
  its ``lidar`` sensor and its ``queues`` crowd (``radius_m``, ``left_x_m``, ``right_x_m``,
  ``spacing_m``, ``step_period_s``), its static segments where they stand and where the
  localizers' map has them (``static_segments``, ``furniture``).
"""

from __future__ import annotations

import functools
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from core.geometry import spanning
from envs.config import WorldConfig, load_world
from envs.crowds import QueuesConfig
from envs.sensors import LidarConfig, OdometryConfig
from localizers.mcl_lidar import LidarMCLParams
from localizers.registry import LOCALIZER_CONFIG_DIR, load_params, params_path
from localizers.scan_filter import FarPointMCLParams

WORLD = "crowded_room"  # the world behind ``crowdloc/CrowdedRoom-v0``


@functools.cache
def room() -> WorldConfig:
    """The crowded room's world config, as shipped."""
    return load_world(WORLD)


def lidar_name() -> str:
    """The name (and sensor) of the room's LIDAR, the one under test."""
    found = room().sensors_of_type("lidar")
    if len(found) != 1:
        raise RuntimeError(f"world {WORLD!r} has {len(found)} lidars, the experiment expects one")
    return next(iter(found))


def lidar() -> LidarConfig:
    """The room's LIDAR."""
    config = room().sensors[lidar_name()]
    if not isinstance(config, LidarConfig):
        raise RuntimeError(f"world {WORLD!r} has no lidar")
    return config


def true_walls_at(height_m: float) -> NDArray[np.float64]:
    """``(S, 4)`` the room's static segments where they stand (not where the map has them) that a
    sensor at ``height_m`` sees: those spanning it (``[bottom, top)``, as the map is cut)."""
    seg = room().static_segments(in_map=False)
    return np.ascontiguousarray(seg[spanning(seg[:, 4], seg[:, 5], height_m), :4])


def moved_furniture() -> list[tuple[str, float]]:
    """``(name, metres)`` of each piece of furniture the localizers' map has elsewhere than where it stands."""
    return [(f.name, float(np.hypot(*f.map_offset_m))) for f in room().furniture if any(f.map_offset_m) or f.map_offset_rad]


def furniture_text(height_m: float | None = None, seen: bool = True) -> str:
    """The room's furniture as ``the name (height)``; with ``height_m`` only the pieces a sensor at
    that height sees (``seen``) or does not see (every piece spans the floor to its height, a
    table's legs and top together)."""
    names = [f"the {f.name} ({f.height_m:g} m)" for f in room().furniture if height_m is None or (height_m < f.height_m) == seen]
    return " and ".join([", ".join(names[:-1]), names[-1]]) if len(names) > 1 else (names[0] if names else "none")


def odometry() -> OdometryConfig:
    """The room's odometry."""
    config = room().sensor_of_type("odometry")
    if not isinstance(config, OdometryConfig):
        raise RuntimeError(f"world {WORLD!r} has no odometry")
    return config


def queues() -> QueuesConfig:
    """The room's queueing crowd."""
    config = room().crowds.get("queues")
    if not isinstance(config, QueuesConfig):
        raise RuntimeError(f"world {WORLD!r} has no queues crowd")
    return config


def people_radius_m() -> float:
    """Radius of the queued people's footprint discs (what collides)."""
    return float(queues().radius_m)


def legs_text() -> str:
    """The queued people's legs as the LIDAR sees them, from the world config's size ranges."""
    p = queues().person

    def cm(lo_hi: tuple[float, ...]) -> str:
        lo, hi = (round(100 * v) for v in lo_hi)
        return f"{lo}-{hi} cm" if lo != hi else f"{lo} cm"

    return (
        f"two leg discs of radius {cm(p.leg_radius_m)}, {cm(tuple(2 * v for v in p.hip_half_width_m))} apart at the hips "
        f"(statures {cm(p.height_m)}), swinging while a person walks"
    )


def crowd_positions(env: Any) -> NDArray[np.float64]:
    """``(P, 2)`` copy of the people's positions in a live env (an env internal)."""
    return np.array(env.world.positions[env.world.member_rows])


def queue_gap_m(center_xy: tuple[float, float], side_m: float) -> float:
    """Clearance between the robot on the square and the queued people (the nearer queue)."""
    q = queues()
    left = center_xy[0] - side_m / 2 - q.left_x_m
    right = q.right_x_m - (center_xy[0] + side_m / 2)
    return min(left, right) - room().robot.radius_m - q.radius_m


def queue_wall_offset_m() -> float:
    """Distance of a queue's line from the side wall behind it (the nearer of the two)."""
    xmin, _, xmax, _ = room().arena_m
    q = queues()
    return min(q.left_x_m - xmin, xmax - q.right_x_m)


@functools.cache
def mcl_defaults() -> LidarMCLParams:
    """``mcl_lidar``'s shipped parameters (``configs/localizers/mcl_lidar.yaml``)."""
    params: LidarMCLParams = load_params("mcl_lidar")
    return params


@functools.cache
def far_point_defaults() -> FarPointMCLParams:
    """``far_point_mcl``'s shipped parameters (``configs/localizers/far_point_mcl.yaml``)."""
    params: FarPointMCLParams = load_params("far_point_mcl")
    return params


def params_file(name: str) -> str:
    """The shipped parameter file of localizer ``name``, relative to the repository root."""
    return str(params_path(name).relative_to(Path(LOCALIZER_CONFIG_DIR).parent.parent))
