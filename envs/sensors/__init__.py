"""Sensors as plug-ins: one module per sensor type, registered by type name.

Built in: ``odometry`` (:mod:`.odometry`), ``bearing_camera`` (:mod:`.bearing_camera`),
``lidar`` (:mod:`.lidar`), ``sonar`` (:mod:`.sonar`) (those two on the shared
:class:`~envs.sensors.ranging.RangeSensor`), ``ceiling_camera`` (:mod:`.ceiling_camera`) and
``stereo_camera`` (:mod:`.stereo_camera`). See :mod:`.base` for the interface and
``docs/architecture.md`` for adding one.

This ``__init__`` imports the built-in modules, which registers them: Python runs it before any
module of the package, so whoever reaches the registry (:mod:`envs.config` imports only
:mod:`.base`) finds the built-in types. A sensor of your own registers itself when its module is
imported; neither this file nor :mod:`envs.config` names it.
"""

from __future__ import annotations

from envs.sensors.base import (
    Sensor,
    SensorBase,
    SensorConfig,
    SensorType,
    build_sensor,
    register_sensor,
    sensor_type,
    sensor_types,
)
from envs.sensors.bearing_camera import BearingCamera, BearingCameraConfig
from envs.sensors.ceiling_camera import CeilingCamera, CeilingCameraConfig
from envs.sensors.lidar import Lidar, LidarConfig
from envs.sensors.odometry import Odometry, OdometryConfig
from envs.sensors.ranging import RangeSensor
from envs.sensors.sonar import Sonar, SonarConfig
from envs.sensors.stereo_camera import StereoCamera, StereoCameraConfig

__all__ = [
    "BearingCamera",
    "BearingCameraConfig",
    "CeilingCamera",
    "CeilingCameraConfig",
    "Lidar",
    "LidarConfig",
    "Odometry",
    "OdometryConfig",
    "RangeSensor",
    "Sensor",
    "SensorBase",
    "SensorConfig",
    "SensorType",
    "Sonar",
    "SonarConfig",
    "StereoCamera",
    "StereoCameraConfig",
    "build_sensor",
    "register_sensor",
    "sensor_type",
    "sensor_types",
]
