"""Measurement kinds as plug-ins: how one sensor's observation becomes what a localizer consumes.

A :class:`MeasurementKind` names the sensor type whose observations it reads and one
``decode(observation, metadata)`` function that turns an observation array (and the
sensor's metadata: beam angles, maximum range, ...) into a measurement dataclass of
:mod:`localizers.base`. The localizer wrapper, the recordings of ``agents.experiments.replay`` and
``crowdloc eval`` go through :func:`decode`, so they handle any registered kind without a
branch on observation keys. Built in: ``bearings`` (a bearing camera's slots), ``scan``
(a LIDAR's ranges), ``ceiling_image`` (an upward camera's image), ``stereo_edges`` (a
stereo camera's typed vertical edges) and ``odometry`` (the increment itself, what dead
reckoning reads in a world without a bearing camera). Each decode checks the observation's
shape against the sensor's metadata (:func:`checked_shape`). This module imports nothing from ``envs``: metadata are plain values.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from core.schema import ConfigError
from localizers.base import BearingMeasurement, EdgeMeasurement, LandmarkMap, MeasurementError, OdometryDelta, ScanMeasurement

Decoder = Callable[[NDArray[np.float32], Mapping[str, Any]], Any]


@dataclass(frozen=True)
class MeasurementKind:
    """A registered measurement kind.

    Attributes:
        name: what localizer specs name (``"bearings"``).
        sensor_type: the registered sensor type whose observations it decodes (``"bearing_camera"``).
        decode: ``decode(observation, metadata) -> measurement``.
        summary: one line for listings.
    """

    name: str
    sensor_type: str
    decode: Decoder
    summary: str = ""


_KINDS: dict[str, MeasurementKind] = {}


def register_measurement(kind: MeasurementKind) -> MeasurementKind:
    """Register ``kind`` (again with the same decoder is fine; another decoder is an error)."""
    current = _KINDS.get(kind.name)
    if current is not None and current != kind:
        raise ValueError(f"measurement kind {kind.name!r} is already registered (decoding {current.sensor_type!r})")
    _KINDS[kind.name] = kind
    return kind


def measurement_kinds() -> list[str]:
    """The registered kinds, in registration order."""
    return list(_KINDS)


def measurement_kind(name: str) -> MeasurementKind:
    """The registered kind ``name``, or a :class:`ConfigError` listing the known ones."""
    if name not in _KINDS:
        raise ConfigError(f"unknown measurement kind {name!r} (registered: {', '.join(_KINDS)})")
    return _KINDS[name]


def decode(kind: str, observation: NDArray[np.float32], metadata: Mapping[str, Any]) -> Any:
    """The measurement of kind ``kind`` in one observation array of its sensor."""
    return measurement_kind(kind).decode(observation, metadata)


def readable_kinds(sensors: Mapping[str, Mapping[str, Any]]) -> list[str]:
    """The registered kinds (in registration order) whose sensor type is among ``sensors`` (name -> metadata with a ``type``)."""
    types = {meta.get("type") for meta in sensors.values()}
    return [name for name, kind in _KINDS.items() if kind.sensor_type in types]


def find_sensor(kind: str, sensors: Mapping[str, Mapping[str, Any]], needed_by: str, name: str | None = None) -> str:
    """The one sensor (by name) among ``sensors`` (name -> metadata with a ``type``) that
    ``kind`` reads, or a :class:`ConfigError` saying which sensor is missing or ambiguous.

    ``name`` picks one of several (a second LIDAR); it must be a sensor of the right type."""
    want = measurement_kind(kind).sensor_type
    a_want = f"{'an' if want[:1] in 'aeiou' else 'a'} {want}"  # "a lidar", "an odometry"
    names = [n for n, meta in sensors.items() if meta.get("type") == want]
    if name is not None:
        if name not in names:
            have = ", ".join(f"{n} ({m.get('type')})" for n, m in sensors.items()) or "none"
            raise ConfigError(
                f"{needed_by}: sensor {name!r} is not {a_want} sensor of this world ({kind} measurements); it has {have}"
            )
        return name
    if not names:
        have = ", ".join(f"{n} ({m.get('type')})" for n, m in sensors.items()) or "none"
        raise ConfigError(f"{needed_by} needs {a_want} sensor ({kind} measurements); this world has {have}")
    if len(names) > 1:
        raise ConfigError(
            f"{needed_by} reads {kind} from {a_want} sensor, and this world has several: {', '.join(names)}; name one "
            "(gym.make(..., localizer_sensor=NAME))"
        )
    return names[0]


def sensor_map(landmarks: LandmarkMap, metadata: Mapping[str, Any]) -> LandmarkMap:
    """The map as the localizer's sensor sees it: cut at the sensor's ``height_m`` when its
    metadata has one (a range sensor sees the walls and furniture spanning its plane only)."""
    height = metadata.get("height_m")
    return landmarks if height is None else landmarks.at_height(float(height))


def checked_shape(
    observation: Any, metadata: Mapping[str, Any] | None, expected: tuple[int, ...] | None, what: str, multiple_of: int = 1
) -> NDArray[Any]:
    """``observation`` as an array of the ``expected`` shape (from the sensor's metadata), or a
    :class:`MeasurementError` naming the observation key (``metadata["key"]``), ``what`` it holds,
    the expected and the actual shape. Without an expected shape (no metadata), a 1-D array whose
    length is a multiple of ``multiple_of`` (the values of one slot)."""
    a = np.asarray(observation)
    ok = a.shape == expected if expected is not None else a.ndim == 1 and a.size % multiple_of == 0
    if not ok:
        key = (metadata or {}).get("key", what)
        want = str(expected) if expected is not None else f"(n,) with n a multiple of {multiple_of}"
        raise MeasurementError(f"observation {key!r} ({what}): expected shape {want}, got {a.shape}")
    return a


def odometry_delta(observation: Any, metadata: Mapping[str, Any] | None = None) -> OdometryDelta:
    """An odometry sensor's ``(3,)`` increment ``(dx, dy, dtheta)`` (robot frame) as an :class:`OdometryDelta`."""
    d = checked_shape(observation, metadata, (3,), "odometry dx, dy, dtheta")
    return OdometryDelta(float(d[0]), float(d[1]), float(d[2]))


def bearing_measurement(landmarks_obs: NDArray[np.float32], metadata: Mapping[str, Any] | None = None) -> BearingMeasurement:
    """Turn the camera's flat ``(3 L,)`` slots ``(visible, cos, sin)`` into a :class:`BearingMeasurement`
    (checked: ``L`` is the metadata's ``landmark_count`` when given)."""
    count = (metadata or {}).get("landmark_count")
    expected = None if count is None else (3 * int(count),)
    slots = checked_shape(landmarks_obs, metadata, expected, "bearing slots: visible, cos, sin per landmark", 3)
    slots = np.asarray(slots, dtype=np.float64).reshape(-1, 3)
    seen = np.flatnonzero(slots[:, 0] > 0.5)
    slots = slots[seen]
    return BearingMeasurement(seen.astype(np.int64), np.arctan2(slots[:, 2], slots[:, 1]))


def scan_measurement(ranges: NDArray[np.float32], metadata: Mapping[str, Any]) -> ScanMeasurement:
    """A LIDAR's ``(B,)`` ranges with the beam angles, maximum range and (where the metadata has
    them: a swept LIDAR) beam lags of its metadata (checked: ``B`` beams)."""
    beams = np.asarray(metadata["beam_angles_rad"]).shape
    lags = metadata.get("beam_lags_s")
    return ScanMeasurement(
        np.asarray(checked_shape(ranges, metadata, beams, "ranges, one per beam"), dtype=np.float64),
        np.asarray(metadata["beam_angles_rad"], dtype=np.float64),
        float(metadata["max_range_m"]),
        None if lags is None else np.asarray(lags, dtype=np.float64),
    )


def ceiling_image_measurement(image: NDArray[Any], metadata: Mapping[str, Any]) -> Any:
    """An upward camera's RGB image with its camera (:class:`localizers.ceiling_target.CeilingImage`;
    checked: ``(height_px, width_px, 3)`` of the metadata)."""
    from localizers.ceiling_target import ceiling_image  # OpenCV is imported only where images are read

    shape = (int(metadata["height_px"]), int(metadata["width_px"]), 3) if "height_px" in metadata else None
    return ceiling_image(checked_shape(image, metadata, shape, "RGB image"), metadata)


def edge_measurement(slots: NDArray[np.float32], metadata: Mapping[str, Any] | None = None) -> EdgeMeasurement:
    """A stereo camera's flat slots ``(valid, type, inverse range, bearing)`` as an
    :class:`EdgeMeasurement` of its valid ones (checked: a NaN or non-positive inverse range
    is a :class:`MeasurementError` naming it; the metadata's ``slots`` count when given)."""
    count = (metadata or {}).get("slots")
    expected = None if count is None else (4 * int(count),)
    rows = checked_shape(slots, metadata, expected, "stereo edge slots: valid, type, inverse range, bearing", 4)
    rows = np.asarray(rows, dtype=np.float64).reshape(-1, 4)
    rows = rows[rows[:, 0] > 0.5]
    return EdgeMeasurement(np.rint(rows[:, 1]).astype(np.int64), rows[:, 2], rows[:, 3]).validated("stereo_edges slots")


BEARINGS = register_measurement(
    MeasurementKind("bearings", "bearing_camera", bearing_measurement, "identified landmark bearings")
)
SCAN = register_measurement(MeasurementKind("scan", "lidar", scan_measurement, "a 2-D range scan"))
CEILING_IMAGE = register_measurement(
    MeasurementKind("ceiling_image", "ceiling_camera", ceiling_image_measurement, "an upward camera's RGB image of the ceiling")
)
STEREO_EDGES = register_measurement(
    MeasurementKind("stereo_edges", "stereo_camera", edge_measurement, "typed vertical edges of a stereo camera")
)
#: the odometry increment itself (every world has the sensor): what a localizer that needs no other
#: sensor reads in a world without its own kind's (``LocalizerSpec.fallback``: dead reckoning)
ODOMETRY = register_measurement(
    MeasurementKind("odometry", "odometry", odometry_delta, "the odometry increment alone (no exteroceptive sensor)")
)
