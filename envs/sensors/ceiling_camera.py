"""An upward-looking colour camera: RGB images of the ceiling above the robot.

The ceiling is the world's ``ceiling`` feature (:mod:`envs.features.ceiling`). Every pixel is
a ray from the camera's centre through the lens; the renderer finds where it meets the
ceiling (or a person's head on the way) and what colour the ceiling has there, then applies
the camera's imperfections. One numba kernel does the whole image.

**Camera frame.** The camera sits ``mount_height_m`` above the floor at ``offset_m``
(forward, left) from the robot's centre and looks straight up, with the top of the image
toward the robot's heading. A camera that looks up sees the ceiling *mirrored* against a map
seen from above: image right (+u) is the robot's **left**, image up (-v) its forward
direction. With ``(x_n, y_n)`` the undistorted normalized coordinates of a pixel (x to the
right, y down), the ceiling point it sees is, in the robot frame,
``forward = -y_n d + offset_forward``, ``left = x_n d + offset_left``, where ``d`` is the
ceiling's height above the camera.

**Imperfections** (each a parameter; the defaults are on unless said otherwise):

- radial lens distortion ``k1`` (Brown's model on normalized coordinates,
  ``x_d = x_u (1 + k1 r_u^2)``, the model OpenCV's ``undistortPoints`` inverts);
- ``pixel_aspect`` (``fy / fx``; 1: square pixels);
- an illumination gain that varies along the corridor with the light panels' pitch and slowly
  over time; vignetting (``1 - vignetting r^2`` toward the corners);
- motion blur: the image is the mean of renders along the motion of the last
  ``exposure_s``, as many as the blur spans pixels (at most ``max_blur_samples``), so a
  moving robot blurs the targets and a stopped one does not;
- heads of the people around the robot, discs of ``head_radius_m`` at ``head_height_m``,
  which hide the ceiling near the edges of the view;
- Gaussian pixel noise of ``noise_std`` (0-255 scale), drawn from a pool refilled from the
  sensor's random stream at every reset and read from a random offset every frame (the pool
  keeps a 320 x 240 frame well under a millisecond).

The observation is ``uint8 (height_px, width_px, 3)``, rendered every ``period_steps`` steps
(the last image is repeated in between).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numba
import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from envs.features.ceiling import LABEL_CEILING, LABEL_HEAD, LABEL_JOINT, CeilingConfig
from envs.sensors.base import SensorBase, SensorConfig, register_sensor
from envs.state import WorldState
from localizers.schema import ConfigError, check

if TYPE_CHECKING:
    from envs.config import WorldConfig

_NOISE_POOL = 1 << 20  # noise values in the pool (a power of two: offsets wrap with a mask)
_HAIR_RGB = (45, 35, 30)


@dataclass(frozen=True)
class CeilingCameraConfig(SensorConfig):
    """An upward RGB camera (see the module docstring for the frame and the effects).

    The default field of view gives the paper's 110 cm x 84 cm footprint on a ceiling
    1.75 m above the camera (a 2.5 m ceiling, the camera 0.75 m up on a Nomad 200).
    """

    key: str = "ceiling_image"
    feature: str = "ceiling"  # the world feature (of type ceiling) it looks at
    width_px: int = 320
    height_px: int = 240
    hfov_rad: float = 2 * math.atan(0.55 / 1.75)  # 34.9 deg across the image's width
    pixel_aspect: float = 1.0  # fy / fx
    mount_height_m: float = 0.75
    offset_m: tuple[float, float] = (0.0, 0.0)  # (forward, left) from the robot's centre
    k1: float = -0.1  # radial distortion (negative: barrel)
    noise_std: float = 3.0  # pixel noise, 0-255 scale
    gain_along_amplitude: float = 0.15  # relative brightness change between and under the lights
    gain_time_amplitude: float = 0.05  # slow relative flicker over time
    gain_time_period_s: float = 7.0
    vignetting: float = 0.25  # relative darkening at the image corners
    exposure_s: float = 1.0 / 60.0  # 0: no motion blur
    max_blur_samples: int = 8
    head_height_m: float = 1.70  # the people's heads, as discs at this height (0: no heads)
    head_radius_m: float = 0.12  # a head with its hair; people pressing on the robot show at the image corners
    period_steps: int = 1  # render every this many steps

    def __post_init__(self) -> None:
        check(16 <= self.width_px <= 4096, f"ceiling_camera.width_px must be in 16..4096, got {self.width_px}")
        check(16 <= self.height_px <= 4096, f"ceiling_camera.height_px must be in 16..4096, got {self.height_px}")
        check(0 < self.hfov_rad < math.radians(150), f"ceiling_camera.hfov_rad must be in (0, 150 deg), got {self.hfov_rad}")
        check(0.2 <= self.pixel_aspect <= 5, f"ceiling_camera.pixel_aspect must be in [0.2, 5], got {self.pixel_aspect}")
        check(self.mount_height_m >= 0, f"ceiling_camera.mount_height_m must be >= 0, got {self.mount_height_m}")
        check(-0.5 <= self.k1 <= 0.5, f"ceiling_camera.k1 must be in [-0.5, 0.5], got {self.k1}")
        for name in ("noise_std", "exposure_s", "head_height_m", "head_radius_m"):
            value = getattr(self, name)
            check(math.isfinite(value) and value >= 0, f"ceiling_camera.{name} must be >= 0, got {value}")
        for name in ("gain_along_amplitude", "gain_time_amplitude", "vignetting"):
            value = getattr(self, name)
            check(0 <= value < 1, f"ceiling_camera.{name} must be in [0, 1), got {value}")
        check(self.gain_time_period_s > 0, f"ceiling_camera.gain_time_period_s must be > 0, got {self.gain_time_period_s}")
        check(self.max_blur_samples >= 1, f"ceiling_camera.max_blur_samples must be >= 1, got {self.max_blur_samples}")
        check(self.period_steps >= 1, f"ceiling_camera.period_steps must be >= 1, got {self.period_steps}")

    def check_world(self, world: WorldConfig, name: str) -> None:
        ceiling = world.features.get(self.feature)
        if not isinstance(ceiling, CeilingConfig):
            ceilings = ", ".join(world.features_of_type("ceiling")) or "none"
            raise ConfigError(
                f"world {world.name!r}: sensor {name!r} looks at feature {self.feature!r}, which is not a ceiling "
                f"(its ceiling features: {ceilings})"
            )
        check(
            ceiling.height_m > self.mount_height_m + 0.1,
            f"world {world.name!r}: sensor {name!r} is mounted at {self.mount_height_m} m, not below the ceiling at {ceiling.height_m} m",
        )
        check(
            self.head_height_m == 0 or self.mount_height_m < self.head_height_m < ceiling.height_m,
            f"world {world.name!r}: sensor {name!r}: head_height_m {self.head_height_m} must lie between the camera "
            f"({self.mount_height_m} m) and the ceiling ({ceiling.height_m} m), or be 0 (no heads)",
        )


class CameraModel:
    """The intrinsics of a :class:`CeilingCameraConfig` and its per-pixel ray table.

    Attributes:
        fx, fy, cx, cy: pinhole intrinsics in pixels (pixel centres at integer + 0.5).
        rays: ``(H, W, 2)`` undistorted normalized ``(x_n, y_n)`` of every pixel's centre.
    """

    def __init__(self, config: CeilingCameraConfig) -> None:
        w, h = config.width_px, config.height_px
        self.fx = (w / 2) / math.tan(config.hfov_rad / 2)
        self.fy = self.fx * config.pixel_aspect
        self.cx, self.cy = w / 2, h / 2
        u, v = np.meshgrid(np.arange(w) + 0.5, np.arange(h) + 0.5)
        self.rays = np.stack(undistort((u - self.cx) / self.fx, (v - self.cy) / self.fy, config.k1), axis=-1)
        r2 = ((u - self.cx) / self.cx) ** 2 + ((v - self.cy) / self.cy) ** 2
        self.vignette = 1.0 - config.vignetting * r2 / 2.0  # 1 - vignetting at the corners (r2 = 2)
        self.max_ray = float(np.max(np.hypot(self.rays[..., 0], self.rays[..., 1])))


def undistort(xd: NDArray[np.float64], yd: NDArray[np.float64], k1: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Invert ``x_d = x_u (1 + k1 r_u^2)`` (normalized coordinates) by fixed-point iteration."""
    xu, yu = np.array(xd, dtype=np.float64), np.array(yd, dtype=np.float64)
    for _ in range(20):
        scale = 1.0 + k1 * (xu * xu + yu * yu)
        xu, yu = xd / scale, yd / scale
    return xu, yu


@numba.njit(cache=True, error_model="numpy", boundscheck=False)
def render_ceiling(
    rays: NDArray[np.float64],
    poses: NDArray[np.float64],
    offset: NDArray[np.float64],
    depth: float,
    head_depth: float,
    heads: NDArray[np.float64],
    head_radius: float,
    base: NDArray[np.float64],
    joint: NDArray[np.float64],
    tile: float,
    tile_x0: float,
    tile_y0: float,
    half_joint: float,
    rects: NDArray[np.float64],
    rect_rgb: NDArray[np.float64],
    rect_label: NDArray[np.int64],
    discs: NDArray[np.float64],
    disc_rgb: NDArray[np.float64],
    disc_label: NDArray[np.int64],
    gain: NDArray[np.float64],
    noise: NDArray[np.float32],
    noise_offset: int,
    image: NDArray[np.uint8],
    labels: NDArray[np.int64],
) -> None:
    """Render ``image`` ``(H, W, 3)`` (and ``labels`` ``(H, W)`` when it is not empty).

    ``poses`` ``(n, 3)``: the camera's robot poses over the exposure (the image is their mean);
    ``gain`` ``(H, W)``: illumination times vignetting; ``noise``: the pool, read from
    ``noise_offset`` on (wrapping; its length is a power of two).
    """
    h, w = rays.shape[0], rays.shape[1]
    n = poses.shape[0]
    mask = noise.shape[0] - 1
    want_labels = labels.shape[0] == h
    inv_tile = 1.0 / tile
    head_r2 = head_radius * head_radius
    cos = np.empty(n)
    sin = np.empty(n)
    for s in range(n):
        cos[s] = math.cos(poses[s, 2])
        sin[s] = math.sin(poses[s, 2])
    for v in range(h):
        for u in range(w):
            xn = rays[v, u, 0]
            yn = rays[v, u, 1]
            acc_r = acc_g = acc_b = 0.0
            label = LABEL_CEILING
            for s in range(n):
                # a head on the way hides the ceiling
                hit_head = False
                if heads.shape[0] > 0:
                    f = -yn * head_depth + offset[0]
                    le = xn * head_depth + offset[1]
                    hx = poses[s, 0] + cos[s] * f - sin[s] * le
                    hy = poses[s, 1] + sin[s] * f + cos[s] * le
                    for k in range(heads.shape[0]):
                        if (hx - heads[k, 0]) ** 2 + (hy - heads[k, 1]) ** 2 < head_r2:
                            hit_head = True
                            break
                if hit_head:
                    acc_r += _HAIR_RGB[0]
                    acc_g += _HAIR_RGB[1]
                    acc_b += _HAIR_RGB[2]
                    label = LABEL_HEAD
                    continue
                f = -yn * depth + offset[0]
                le = xn * depth + offset[1]
                X = poses[s, 0] + cos[s] * f - sin[s] * le
                Y = poses[s, 1] + sin[s] * f + cos[s] * le
                # the tiles and their joints, then the primitives in drawing order
                fx = (X - tile_x0) * inv_tile
                fy = (Y - tile_y0) * inv_tile
                if abs(fx - math.floor(fx + 0.5)) * tile < half_joint or abs(fy - math.floor(fy + 0.5)) * tile < half_joint:
                    r, g, b = joint[0], joint[1], joint[2]
                    label = LABEL_JOINT
                else:
                    r, g, b = base[0], base[1], base[2]
                    label = LABEL_CEILING
                for k in range(rects.shape[0]):
                    if rects[k, 0] <= X < rects[k, 2] and rects[k, 1] <= Y < rects[k, 3]:
                        r, g, b = rect_rgb[k, 0], rect_rgb[k, 1], rect_rgb[k, 2]
                        label = rect_label[k]
                for k in range(discs.shape[0]):
                    if (X - discs[k, 0]) ** 2 + (Y - discs[k, 1]) ** 2 < discs[k, 2] * discs[k, 2]:
                        r, g, b = disc_rgb[k, 0], disc_rgb[k, 1], disc_rgb[k, 2]
                        label = disc_label[k]
                acc_r += r
                acc_g += g
                acc_b += b
            scale = gain[v, u] / n
            i = (v * w + u) * 3
            value = acc_r * scale + noise[(noise_offset + i) & mask]
            image[v, u, 0] = 0 if value <= 0.0 else (255 if value >= 255.0 else int(value + 0.5))
            value = acc_g * scale + noise[(noise_offset + i + 1) & mask]
            image[v, u, 1] = 0 if value <= 0.0 else (255 if value >= 255.0 else int(value + 0.5))
            value = acc_b * scale + noise[(noise_offset + i + 2) & mask]
            image[v, u, 2] = 0 if value <= 0.0 else (255 if value >= 255.0 else int(value + 0.5))
            if want_labels:
                labels[v, u] = label


@register_sensor("ceiling_camera", CeilingCameraConfig)
class CeilingCamera(SensorBase):
    """Renders the ceiling above the robot as an RGB image (module docstring).

    Observation ``uint8 (height_px, width_px, 3)``. :meth:`render` renders any pose, with the
    pixel labels of :mod:`envs.features.ceiling` when asked (to learn colour thresholds from
    images whose truth is known).
    """

    draw_layer = "over"

    def __init__(self, name: str, config: CeilingCameraConfig, world: WorldConfig, state: WorldState) -> None:
        self.name = name
        self.key = config.key
        self.config = config
        ceiling = world.features[config.feature]
        assert isinstance(ceiling, CeilingConfig)  # checked by CeilingCameraConfig.check_world
        self.ceiling = ceiling
        self.model = CameraModel(config)
        self.depth = ceiling.height_m - config.mount_height_m
        self.head_depth = config.head_height_m - config.mount_height_m
        self.dt_s = world.dt_s
        prims = ceiling.primitives(world.arena_m)
        self._prims = prims
        self._rect_lo = np.minimum(prims.rects[:, :2], prims.rects[:, 2:])
        self._rect_hi = np.maximum(prims.rects[:, :2], prims.rects[:, 2:])
        self._base = np.asarray(ceiling.rgb, dtype=np.float64)
        self._joint = np.asarray(ceiling.joint_rgb, dtype=np.float64)
        self._offset = np.asarray(config.offset_m, dtype=np.float64)
        # how far from the robot's centre the view reaches on the ceiling
        self.reach_m = self.model.max_ray * self.depth + float(np.hypot(*self._offset))
        self._rows = state.crowd_rows
        self._noise = np.zeros(_NOISE_POOL, dtype=np.float32)
        self._image = np.zeros((config.height_px, config.width_px, 3), dtype=np.uint8)
        self._no_labels = np.zeros((0, 0), dtype=np.int64)
        self._previous_pose: NDArray[np.float64] | None = None
        self._steps = 0
        self._fresh = True
        self._phase = 0.0

    def space(self) -> spaces.Box:
        c = self.config
        return spaces.Box(0, 255, shape=(c.height_px, c.width_px, 3), dtype=np.uint8)

    def reset(self) -> None:
        self._previous_pose = None
        self._steps = 0
        self._fresh = True

    def metadata(self) -> dict[str, Any]:
        c, m = self.config, self.model
        return {
            "width_px": c.width_px,
            "height_px": c.height_px,
            "fx_px": m.fx,
            "fy_px": m.fy,
            "cx_px": m.cx,
            "cy_px": m.cy,
            "k1": c.k1,
            "mount_height_m": c.mount_height_m,
            "ceiling_height_m": self.ceiling.height_m,
            "offset_m": tuple(c.offset_m),
            "mirrored": True,  # image right is the robot's left
            "feature": c.feature,
        }

    # ------------------------------------------------------------------ rendering
    def seed_noise(self, rng: np.random.Generator) -> None:
        """Refill the pixel-noise pool from ``rng`` (done at the first frame after every reset)."""
        self._noise = (rng.standard_normal(_NOISE_POOL) * self.config.noise_std).astype(np.float32)

    def gain(self, pose: NDArray[np.float64], time_s: float, phase: float = 0.0) -> float:
        """The illumination gain at the camera's view centre: brighter under the light panels."""
        c, ce = self.config, self.ceiling
        along = c.gain_along_amplitude * math.cos(2 * math.pi * (float(pose[1]) - ce.light_first_y_m) / ce.light_pitch_m)
        over_time = c.gain_time_amplitude * math.sin(2 * math.pi * time_s / c.gain_time_period_s + phase)
        return (1.0 + along) * (1.0 + over_time)

    def render(
        self,
        poses: NDArray[np.float64],
        heads_xy: NDArray[np.float64] | None = None,
        gain: float = 1.0,
        noise_offset: int | None = None,
        labels: bool = False,
    ) -> tuple[NDArray[np.uint8], NDArray[np.int64] | None]:
        """The image of the mean over ``poses`` ``(n, 3)`` (robot poses; one row: no blur).

        Args:
            heads_xy: ``(k, 2)`` head centres of the people near the robot (none by default).
            gain: the illumination gain (vignetting is added); ``noise_offset``: where the
                noise pool is read (None: no noise).
            labels: also return the ``(H, W)`` label of every pixel (of the last pose).
        """
        c = self.config
        poses = np.ascontiguousarray(np.asarray(poses, dtype=np.float64).reshape(-1, 3))
        lo = poses[:, :2].min(axis=0) - self.reach_m
        hi = poses[:, :2].max(axis=0) + self.reach_m
        p = self._prims
        near = np.flatnonzero(np.all((self._rect_hi >= lo) & (self._rect_lo <= hi), axis=1))
        dnear = np.flatnonzero(
            np.all((p.discs[:, :2] + p.discs[:, 2:3] >= lo) & (p.discs[:, :2] - p.discs[:, 2:3] <= hi), axis=1)
        )
        heads = (
            np.zeros((0, 2))
            if heads_xy is None or c.head_height_m == 0
            else np.asarray(heads_xy, dtype=np.float64).reshape(-1, 2)
        )
        if heads.shape[0]:
            head_reach = self.model.max_ray * self.head_depth + float(np.hypot(*self._offset)) + c.head_radius_m
            keep = np.all(
                (heads >= poses[:, :2].min(axis=0) - head_reach) & (heads <= poses[:, :2].max(axis=0) + head_reach), axis=1
            )
            heads = np.ascontiguousarray(heads[keep])
        image = np.empty((c.height_px, c.width_px, 3), dtype=np.uint8)
        label_image = np.empty((c.height_px, c.width_px), dtype=np.int64) if labels else self._no_labels
        noise = self._noise if noise_offset is not None else np.zeros(1, dtype=np.float32)
        ce = self.ceiling
        render_ceiling(
            self.model.rays, poses, self._offset, self.depth, self.head_depth, heads, c.head_radius_m,
            self._base, self._joint, ce.tile_m, ce.tile_origin_m[0], ce.tile_origin_m[1], ce.joint_width_m / 2,
            np.ascontiguousarray(p.rects[near]), np.ascontiguousarray(p.rect_rgb[near]), p.rect_label[near],
            np.ascontiguousarray(p.discs[dnear]), np.ascontiguousarray(p.disc_rgb[dnear]), p.disc_label[dnear],
            self.model.vignette * gain, noise, int(noise_offset or 0), image, label_image,
        )  # fmt: skip
        return image, (label_image if labels else None)

    def exposure_poses(self, pose: NDArray[np.float64]) -> NDArray[np.float64]:
        """The poses the image averages: along the motion from the last step over the exposure time."""
        c, prev = self.config, self._previous_pose
        if c.exposure_s == 0 or prev is None:
            return pose[None, :]
        frac = min(1.0, c.exposure_s / self.dt_s)
        dtheta = (pose[2] - prev[2] + math.pi) % (2 * math.pi) - math.pi
        # pixels the view centre and the image corners sweep during the exposure
        sweep_m = frac * (math.hypot(pose[0] - prev[0], pose[1] - prev[1]) + abs(dtheta) * self.reach_m)
        samples = min(c.max_blur_samples, max(1, math.ceil(sweep_m * self.model.fx / self.depth)))
        if samples == 1:
            return pose[None, :]
        t = 1.0 - frac * (1.0 - (np.arange(samples) + 0.5) / samples)  # from 1 - frac to 1, mid-sample
        start = pose - np.array([pose[0] - prev[0], pose[1] - prev[1], dtheta])
        return start[None, :] + t[:, None] * (pose - start)[None, :]

    def observe(self, state: WorldState, rng: np.random.Generator) -> tuple[NDArray[np.uint8], dict[str, Any]]:
        c = self.config
        pose = state.robot_pose
        if self._fresh:
            self.seed_noise(rng)
            self._phase = float(rng.uniform(0.0, 2 * math.pi))  # where in its flicker the light starts
            self._fresh = False
        rendered = self._steps % c.period_steps == 0
        if rendered:
            offset = int(rng.integers(_NOISE_POOL)) if c.noise_std > 0 else None
            heads = state.positions[self._rows] if c.head_height_m > 0 else None
            self._image, _ = self.render(self.exposure_poses(pose), heads, self.gain(pose, state.time_s, self._phase), offset)
        self._steps += 1
        self._previous_pose = pose
        # a repeated frame is a copy: every step hands out its own array
        return (self._image if rendered else self._image.copy()), {}

    def draw(self, canvas: Any, state: WorldState, reading: NDArray[np.uint8], info: Mapping[str, Any]) -> None:
        """The view's footprint on the ceiling, as an outline."""
        c = self.config
        x, y, th = state.robot_pose
        corners = []
        for u, v in ((0, 0), (c.width_px - 1, 0), (c.width_px - 1, c.height_px - 1), (0, c.height_px - 1)):
            xn, yn = self.model.rays[v, u]
            f, le = -yn * self.depth + c.offset_m[0], xn * self.depth + c.offset_m[1]
            corners.append((x + math.cos(th) * f - math.sin(th) * le, y + math.sin(th) * f + math.cos(th) * le))
        for a, b in zip(corners, corners[1:] + corners[:1]):
            canvas.line(a, b, (255, 170, 0), 1)
