"""An upward-looking colour camera: RGB images of the ceiling above the robot.

The ceiling is the world's ``ceiling`` feature (:mod:`envs.features.ceiling`), rasterized once
per process into a texture finer than a pixel's footprint. Every pixel is a ray from the
camera's centre through the lens; where it meets the ceiling is an affine function of the
robot's pose, so a frame is one ``cv2.remap`` of the texture. Heads of people in the view are
painted over it, then the camera's imperfections are applied.

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
- the light's colour (off by default): with ``white_balance_k`` set, the light's correlated
  colour temperature (``cct_k``: under the light panels and midway between them, following the
  panels' pitch like the brightness) against the camera's fixed white balance gives every
  channel its own gain (:func:`envs.sensors.light_colour.white_balance_gains`), green keeping the brightness gain; a light
  warmer than the white balance turns the image red, a cooler one blue; ``daylight_cct_k`` draws
  the light midway between the panels (daylight through the doors) per episode from a range, and
  ``auto_white_balance`` replaces the fixed balance by a grey-world one over each frame (both off);
- a specular glare spot on the targets' glossy tape (off by default): ``glare`` gives the lamps hung
  below the ceiling that the tape mirrors into the camera (:mod:`envs.sensors.glare`: the spot's place
  by the mirror geometry, a Blinn-Phong lobe, clipped by the sensor's saturation);
- motion blur: the image, rendered at the middle of the last ``exposure_s`` of the step, is
  smeared along the motion over that time, so a moving robot blurs the targets and a stopped
  one does not. Both the translation (the same smear over the image) and the turn (a smear
  along arcs around the image point under the rotation axis, growing with the distance from
  it and with turn rate x exposure) are modelled: the image is cut into tiles of about
  40 x 40 pixels, each blurred by the line kernel of its centre's motion (``exposure_s`` 0:
  no blur of either kind);
- heads of the people around the robot, discs of ``head_radius_m`` at ``head_height_m``,
  which hide the ceiling near the edges of the view;
- Gaussian pixel noise of ``noise_std`` (0-255 scale), drawn from a pool refilled from the
  sensor's random stream at every reset and read from a random offset every frame (the pool
  keeps a 320 x 240 frame well under a millisecond).

The observation is ``uint8 (height_px, width_px, 3)``, rendered every ``period_steps`` steps
(the last image is repeated in between).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import cv2
import numba
import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from core.geometry import undistort
from core.schema import ConfigError, check, check_ranges
from envs.features.ceiling import LABEL_CEILING, LABEL_HEAD, LABEL_JOINT, CeilingConfig
from envs.sensors.base import SensorBase, SensorConfig, register_sensor
from envs.sensors.exposure import blur_expose
from envs.sensors.glare import Glare, GlareConfig
from envs.sensors.light_colour import cct_white_rgb, check_light, grey_world_gains, white_balance_gains
from envs.state import WorldState

if TYPE_CHECKING:
    from envs.config import WorldConfig

_NOISE_POOL = 1 << 20  # noise offsets drawn per frame (the pool holds this plus one frame)
#: the most memory the rendered ceiling may take (an RGB and a label byte per texel over the arena):
#: the corridor's 3.2 m x 25 m at the default 2.5 mm texel takes 49 MiB
MAX_TEXTURE_BYTES = 1 << 30
_HAIR_RGB = (45, 35, 30)
_BLUR_TILE_PX = 40  # the motion blur's kernel is one per tile of about this many pixels a side

#: overrides that switch the camera's imperfections off (no lens distortion, noise, light changes,
#: vignetting or motion blur; heads still show): an ideal pinhole camera, for tests and studies
IDEAL = {
    "k1": 0.0,
    "noise_std": 0.0,
    "vignetting": 0.0,
    "gain_along_amplitude": 0.0,
    "gain_time_amplitude": 0.0,
    "exposure_s": 0.0,
    "white_balance_k": 0.0,
    "cct_k": (0.0, 0.0),
}


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
    # The light's colour (off by default: the shipped corridor's light is colourless). To turn it on,
    # set the camera's fixed white balance, e.g. white_balance_k: 6500 (sRGB's D65 white, a camera's daylight
    # preset), and the light's CCT: cct_k: [4230, 5500] (under the panels cool-white fluorescent tubes, CIE
    # illuminant F2, CCT 4230 K; midway between them more daylight through the doors, CIE D55, 5503 K;
    # CIE 15:2004, Colorimetry, tables T.6 and T.8).
    white_balance_k: float = 0.0  # the camera's white balance, K (0: no colour change, every channel the same gain)
    cct_k: tuple[float, float] = (0.0, 0.0)  # the light's CCT under the panels and midway between them, K
    # Daylight over the day (off): the light midway between the panels drawn per episode from this range, K, in place
    # of cct_k[1], e.g. daylight_cct_k: [5000, 7500], CIE's representative daylight phases D50 to D75 (CIE 15:2004, 3.1)
    daylight_cct_k: tuple[float, float] = (0.0, 0.0)
    # Auto white balance (off), in place of white_balance_k: grey world, every frame's mean made grey (G. Buchsbaum,
    # "A spatial processor model for object colour perception", J. Franklin Inst. 310(1), 1980, 1-26)
    auto_white_balance: bool = False
    glare: GlareConfig = GlareConfig()  # the tape's glare spot (off: no lamps; envs/sensors/glare.py)
    texel_m: float = 0.0025  # the rendered ceiling's resolution (a pixel sees 3.4 mm of it)
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
        check_ranges(self, "ceiling_camera", non_negative=("noise_std", "exposure_s", "head_height_m", "head_radius_m"))
        for name in ("gain_along_amplitude", "gain_time_amplitude", "vignetting"):
            value = getattr(self, name)
            check(0 <= value < 1, f"ceiling_camera.{name} must be in [0, 1), got {value}")
        check(0 < self.texel_m <= 0.01, f"ceiling_camera.texel_m must be in (0, 0.01], got {self.texel_m}")
        check(self.gain_time_period_s > 0, f"ceiling_camera.gain_time_period_s must be > 0, got {self.gain_time_period_s}")
        check(self.period_steps >= 1, f"ceiling_camera.period_steps must be >= 1, got {self.period_steps}")
        check_light(self.white_balance_k, self.cct_k, self.daylight_cct_k, self.auto_white_balance, "ceiling_camera")

    @property
    def colour(self) -> bool:
        """Whether the light's colour is modelled (``cct_k`` set, with a white balance fixed or automatic)."""
        return self.cct_k[0] > 0

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
        self.glare.check_ceiling(ceiling.height_m, f"world {world.name!r}: sensor {name!r}")
        check(
            self.head_height_m == 0 or self.mount_height_m < self.head_height_m < ceiling.height_m,
            f"world {world.name!r}: sensor {name!r}: head_height_m {self.head_height_m} must lie between the camera "
            f"({self.mount_height_m} m) and the ceiling ({ceiling.height_m} m), or be 0 (no heads)",
        )
        xmin, ymin, xmax, ymax = world.arena_m
        cols, rows = math.ceil((xmax - xmin) / self.texel_m), math.ceil((ymax - ymin) / self.texel_m)
        check(
            4 * cols * rows <= MAX_TEXTURE_BYTES,
            f"world {world.name!r}: sensor {name!r}: texel_m {self.texel_m} over the {xmax - xmin:g} m x {ymax - ymin:g} m "
            f"arena renders a ceiling of {cols} x {rows} texels, {4 * cols * rows / 2**30:.3g} GiB (RGB and labels), more than "
            f"{MAX_TEXTURE_BYTES / 2**30:g} GiB; give a larger texel_m",
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
        self.k1 = config.k1

    def project(
        self, forward: NDArray[np.float64], left: NDArray[np.float64], depth: float, offset_m: tuple[float, float]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The pixel ``(u, v)`` (distorted) where a robot-frame point ``depth`` above the camera shows."""
        xu, yu = (left - offset_m[1]) / depth, -(forward - offset_m[0]) / depth
        scale = 1 + self.k1 * (xu * xu + yu * yu)
        return self.cx + self.fx * xu * scale, self.cy + self.fy * yu * scale


@functools.lru_cache(maxsize=4)
def ceiling_texture(
    ceiling: CeilingConfig, extent_m: tuple[float, float, float, float], texel_m: float
) -> tuple[NDArray[np.uint8], NDArray[np.uint8]]:
    """The ceiling over ``extent_m`` as an RGB texture and a label texture, ``texel_m`` per texel.

    Texel ``(row, col)`` has its centre at ``(xmin + (col + 0.5) texel_m, ymin + (row + 0.5) texel_m)``
    and shows what the ceiling has there: tiles, joints, then the primitives in drawing order.
    Cached: the envs of one process share their ceiling's texture (read-only).
    """
    xmin, ymin, xmax, ymax = extent_m
    cols, rows = int(math.ceil((xmax - xmin) / texel_m)), int(math.ceil((ymax - ymin) / texel_m))
    xs = np.asarray(xmin + (np.arange(cols) + 0.5) * texel_m, dtype=np.float64)
    ys = np.asarray(ymin + (np.arange(rows) + 0.5) * texel_m, dtype=np.float64)
    rgb = np.empty((rows, cols, 3), dtype=np.uint8)
    rgb[:] = ceiling.rgb
    labels = np.full((rows, cols), LABEL_CEILING, dtype=np.uint8)

    def on_joint(v: NDArray[np.float64], origin: float) -> NDArray[np.bool_]:
        f = (v - origin) / ceiling.tile_m
        return np.asarray(np.abs(f - np.round(f)) * ceiling.tile_m < ceiling.joint_width_m / 2)

    joint_cols, joint_rows = on_joint(xs, ceiling.tile_origin_m[0]), on_joint(ys, ceiling.tile_origin_m[1])
    rgb[:, joint_cols] = ceiling.joint_rgb
    rgb[joint_rows, :] = ceiling.joint_rgb
    labels[:, joint_cols] = LABEL_JOINT
    labels[joint_rows, :] = LABEL_JOINT
    prims = ceiling.primitives(extent_m)

    def texels(lo: float, hi: float, origin: float, count: int) -> slice:
        """The texels whose centres lie in ``[lo, hi)``."""
        return slice(max(0, math.ceil((lo - origin) / texel_m - 0.5)), min(count, math.ceil((hi - origin) / texel_m - 0.5)))

    for (x0, y0, x1, y1), colour, label in zip(prims.rects, prims.rect_rgb, prims.rect_label):
        window = (texels(y0, y1, ymin, rows), texels(x0, x1, xmin, cols))
        rgb[window] = colour.astype(np.uint8)
        labels[window] = label
    for (x, y, r), colour, label in zip(prims.discs, prims.disc_rgb, prims.disc_label):
        rs, cs = texels(y - r, y + r, ymin, rows), texels(x - r, x + r, xmin, cols)
        inside = (xs[cs][None, :] - x) ** 2 + (ys[rs][:, None] - y) ** 2 < r * r
        rgb[rs, cs][inside] = colour.astype(np.uint8)
        labels[rs, cs][inside] = label
    rgb.setflags(write=False)
    labels.setflags(write=False)
    return rgb, labels


@numba.njit(cache=True, error_model="numpy", boundscheck=False)
def draw_heads(
    forward: NDArray[np.float32],
    left: NDArray[np.float32],
    pose: NDArray[np.float64],
    heads: NDArray[np.float64],
    radius: float,
    boxes: NDArray[np.int64],
    image: NDArray[np.uint8],
    labels: NDArray[np.uint8],
) -> None:
    """Paint the heads over ``image`` (and ``labels`` when it is not empty).

    Pixel ``(v, u)`` inside head ``k``'s box ``(v0, v1, u0, u1)`` shows hair where its ray, at the
    heads' height (``forward``, ``left``: the ray's robot-frame point there), passes within
    ``radius`` of the head's centre.
    """
    cos, sin = math.cos(pose[2]), math.sin(pose[2])
    want_labels = labels.shape[0] == image.shape[0]
    r2 = radius * radius
    for k in range(heads.shape[0]):
        for v in range(boxes[k, 0], boxes[k, 1]):
            for u in range(boxes[k, 2], boxes[k, 3]):
                f, le = forward[v, u], left[v, u]
                x = pose[0] + cos * f - sin * le
                y = pose[1] + sin * f + cos * le
                if (x - heads[k, 0]) ** 2 + (y - heads[k, 1]) ** 2 < r2:
                    image[v, u, 0] = _HAIR_RGB[0]
                    image[v, u, 1] = _HAIR_RGB[1]
                    image[v, u, 2] = _HAIR_RGB[2]
                    if want_labels:
                        labels[v, u] = LABEL_HEAD


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
        self.texel_m = config.texel_m
        # how far from the robot's centre a head can be and still show: the view's reach at the
        # heads' height, the camera's offset and the head's radius
        self._head_reach_m = self.model.max_ray * self.head_depth + float(np.hypot(*config.offset_m)) + config.head_radius_m
        self._texture, self._labels = ceiling_texture(ceiling, world.arena_m, config.texel_m)
        self._texture_origin = world.arena_m[:2]
        rays = self.model.rays
        # every pixel's ray: its robot-frame point on the ceiling and at the heads' height
        self._forward = np.ascontiguousarray(-rays[..., 1] * self.depth + config.offset_m[0], dtype=np.float32)
        self._left = np.ascontiguousarray(rays[..., 0] * self.depth + config.offset_m[1], dtype=np.float32)
        self._head_forward = np.ascontiguousarray(-rays[..., 1] * self.head_depth + config.offset_m[0], dtype=np.float32)
        self._head_left = np.ascontiguousarray(rays[..., 0] * self.head_depth + config.offset_m[1], dtype=np.float32)
        self._vignette = np.repeat(self.model.vignette.astype(np.float32).reshape(-1), 3)
        self._tile_v, self._tile_u, self._tile_jacobian = self._blur_tiles()
        self._rows = state.crowd_rows
        frame = config.height_px * config.width_px * 3
        self._noise = np.zeros(_NOISE_POOL + frame, dtype=np.float32)
        self._image = np.zeros((config.height_px, config.width_px, 3), dtype=np.uint8)
        self._no_labels = np.zeros((0, 0), dtype=np.uint8)
        self._no_noise = np.zeros(frame, dtype=np.float32)
        self._no_glare = np.zeros(0, dtype=np.float32)
        self._glare = None
        if config.glare.on:
            self._glare = Glare(config.glare, self._forward, self._left, self.depth, ceiling.height_m, config.offset_m)
        self._no_motion = np.zeros((len(self._tile_v) - 1, len(self._tile_u) - 1, 2))
        self._previous_pose: NDArray[np.float64] | None = None
        self._steps = 0
        self._fresh = True
        self._phase = 0.0
        self.daylight_k = 0.0  # this episode's daylight CCT, K (0: cct_k[1])

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
        self._noise = (rng.standard_normal(self._noise.shape[0]) * self.config.noise_std).astype(np.float32)

    def _under_panels(self, pose: NDArray[np.float64]) -> float:
        """Where the view's centre lies between the light panels: 1 under a panel, -1 midway between two."""
        ce = self.ceiling
        return math.cos(2 * math.pi * (float(pose[1]) - ce.light_first_y_m) / ce.light_pitch_m)

    def gain(self, pose: NDArray[np.float64], time_s: float, phase: float = 0.0) -> float:
        """The illumination gain at the camera's view centre: brighter under the light panels."""
        c = self.config
        along = c.gain_along_amplitude * self._under_panels(pose)
        over_time = c.gain_time_amplitude * math.sin(2 * math.pi * time_s / c.gain_time_period_s + phase)
        return (1.0 + along) * (1.0 + over_time)

    def light_cct_k(self, pose: NDArray[np.float64]) -> float:
        """The light's colour temperature at the view's centre: ``cct_k[0]`` under a panel,
        ``cct_k[1]`` (or this episode's daylight, ``daylight_cct_k``) midway between two, following the
        panels' pitch as the brightness does."""
        under, between = self.config.cct_k
        between = self.daylight_k or between
        return between + (under - between) * (1.0 + self._under_panels(pose)) / 2.0

    def channel_gains(self, pose: NDArray[np.float64], time_s: float, phase: float = 0.0) -> NDArray[np.float64]:
        """The ``(3,)`` gain of each RGB channel: the brightness :meth:`gain` on every channel, times
        the light's colour against the white balance (:func:`envs.sensors.light_colour.white_balance_gains`) when modelled;
        with ``auto_white_balance`` the light's raw colour, which :meth:`render` balances by the frame."""
        c, gain = self.config, self.gain(pose, time_s, phase)
        if not c.colour:
            return np.full(3, gain)
        if c.auto_white_balance:
            return gain * cct_white_rgb(self.light_cct_k(pose))
        return gain * white_balance_gains(self.light_cct_k(pose), c.white_balance_k)

    def render(
        self,
        pose: NDArray[np.float64],
        heads_xy: NDArray[np.float64] | None = None,
        gain: float | NDArray[np.float64] = 1.0,
        noise_offset: int | None = None,
        labels: bool = False,
        previous: NDArray[np.float64] | None = None,
    ) -> tuple[NDArray[np.uint8], NDArray[np.uint8] | None]:
        """The image at robot pose ``pose`` (3,).

        The ceiling texture (finer than a pixel's footprint) is sampled at the point where every
        pixel's ray meets the ceiling, the heads are painted over it, then come the motion blur,
        the glare, the illumination gain with the vignetting, and the noise (one pass: :func:`envs.sensors.exposure.blur_expose`).

        Args:
            heads_xy: ``(k, 2)`` head centres of the people near the robot (none by default).
            gain: the illumination gain (vignetting is added), one for every channel or ``(3,)``, one
                per RGB channel (:meth:`channel_gains`); ``noise_offset``: where the
                noise pool is read (None: no noise).
            labels: also return the ``(H, W)`` label of every pixel (of the sharp image).
            previous: the pose one step earlier: the image is then blurred by the motion over
                the exposure, translation and turn (:meth:`motion_blur`), rendered sharp at
                mid-exposure.
        """
        c = self.config
        pose = np.asarray(pose, dtype=np.float64).reshape(3)
        motion = None
        if previous is not None:
            pose, motion = self.motion_blur(pose, np.asarray(previous, dtype=np.float64).reshape(3))
        cos, sin = math.cos(pose[2]), math.sin(pose[2])
        t, (xmin, ymin) = self.texel_m, self._texture_origin
        # texture coordinates of every pixel's ceiling point: affine in its robot-frame point
        map_x = cv2.addWeighted(self._forward, cos / t, self._left, -sin / t, (pose[0] - xmin) / t - 0.5)
        map_y = cv2.addWeighted(self._forward, sin / t, self._left, cos / t, (pose[1] - ymin) / t - 0.5)
        image: NDArray[np.uint8] = np.asarray(
            cv2.remap(self._texture, map_x, map_y, cv2.INTER_NEAREST, borderMode=cv2.BORDER_REPLICATE), dtype=np.uint8
        )
        label_image = self._no_labels
        if labels or self._glare is not None:  # the glare lights the tape's pixels
            label_image = np.asarray(
                cv2.remap(self._labels, map_x, map_y, cv2.INTER_NEAREST, borderMode=cv2.BORDER_REPLICATE), dtype=np.uint8
            )
        if heads_xy is not None and c.head_height_m > 0 and len(heads_xy):
            self._draw_heads(pose, np.asarray(heads_xy, dtype=np.float64).reshape(-1, 2), image, label_image)
        lit = None if self._glare is None else self._glare.image(pose, label_image)
        glare, glare_rows = (self._no_glare, (0, 0)) if lit is None else (lit[0], lit[1:])
        if c.auto_white_balance:
            gain = grey_world_gains(gain, cv2.mean(image)[:3])
        pad = 0
        if motion is None or not (np.abs(motion) >= 0.35).any():  # no tile's motion reaches half a pixel
            motion = self._no_motion
        else:
            pad = int(math.ceil(float(np.abs(motion).max()) / 2)) + 2  # beyond every kernel's reach
            image = np.asarray(cv2.copyMakeBorder(image, pad, pad, pad, pad, cv2.BORDER_REPLICATE), dtype=np.uint8)
            if lit is not None:  # the blur reaches pad rows beyond the lit ones
                glare = np.asarray(cv2.copyMakeBorder(glare, pad, pad, pad, pad, cv2.BORDER_REPLICATE), dtype=np.float32)
                glare_rows = (glare_rows[0] - pad, glare_rows[1] + pad)
        out = np.empty((c.height_px, c.width_px, 3), dtype=np.uint8)
        if noise_offset is None:
            noise = self._no_noise
        else:
            start = int(noise_offset) % _NOISE_POOL
            noise = self._noise[start : start + out.size]
        gains = np.full(3, float(gain)) if np.ndim(gain) == 0 else np.asarray(gain, dtype=np.float64).reshape(3)
        blur_expose(
            image,
            pad,
            self._tile_v,
            self._tile_u,
            motion,
            self._vignette,
            gains,
            noise,
            glare.reshape(-1),
            glare_rows,
            out,
        )
        return out, (label_image if labels else None)

    def _draw_heads(
        self, pose: NDArray[np.float64], heads: NDArray[np.float64], image: NDArray[np.uint8], labels: NDArray[np.uint8]
    ) -> None:
        """Paint the heads in view, each tested only inside its projected box."""
        c, m = self.config, self.model
        rel = heads - pose[:2]
        near = np.abs(rel).max(axis=1) <= self._head_reach_m  # most frames: nobody close enough
        if not near.any():
            return
        heads, rel = heads[near], rel[near]
        cos, sin = math.cos(pose[2]), math.sin(pose[2])
        forward = cos * rel[:, 0] + sin * rel[:, 1] - c.offset_m[0]
        left = -sin * rel[:, 0] + cos * rel[:, 1] - c.offset_m[1]
        # the head's centre and radius in normalized coordinates at its height, then its box in
        # pixels, widened for the lens (its distortion moves points by under 5 % of their radius)
        xn, yn, rn = left / self.head_depth, -forward / self.head_depth, c.head_radius_m / self.head_depth
        spread = 1.1 * rn + 0.05 * np.hypot(xn, yn)
        u0 = np.floor(m.cx + (xn - spread) * m.fx).astype(np.int64)
        u1 = np.ceil(m.cx + (xn + spread) * m.fx).astype(np.int64) + 1
        v0 = np.floor(m.cy + (yn - spread) * m.fy).astype(np.int64)
        v1 = np.ceil(m.cy + (yn + spread) * m.fy).astype(np.int64) + 1
        boxes = np.stack(
            [np.clip(v0, 0, c.height_px), np.clip(v1, 0, c.height_px), np.clip(u0, 0, c.width_px), np.clip(u1, 0, c.width_px)],
            axis=1,
        )
        seen = (boxes[:, 1] > boxes[:, 0]) & (boxes[:, 3] > boxes[:, 2])
        if seen.any():
            draw_heads(self._head_forward, self._head_left, pose, np.ascontiguousarray(heads[seen]), c.head_radius_m,
                       np.ascontiguousarray(boxes[seen]), image, labels)  # fmt: skip

    def _blur_tiles(self) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.float64]]:
        """The blur's tiles (row and column bounds) and, for each, how the ceiling point at its
        centre moves through the image with the robot's motion: ``(rows, cols, 2, 3)``, the
        pixel motion ``(du, dv)`` per unit of ``(forward, left, turn)`` of the robot (in its
        frame), the lens included."""
        c = self.config
        tile_v = np.linspace(0, c.height_px, max(1, round(c.height_px / _BLUR_TILE_PX)) + 1).round().astype(np.int64)
        tile_u = np.linspace(0, c.width_px, max(1, round(c.width_px / _BLUR_TILE_PX)) + 1).round().astype(np.int64)
        vc, uc = np.meshgrid((tile_v[:-1] + tile_v[1:]) / 2, (tile_u[:-1] + tile_u[1:]) / 2, indexing="ij")
        m = self.model
        xn, yn = undistort((uc - m.cx) / m.fx, (vc - m.cy) / m.fy, c.k1)
        forward, left = -yn * self.depth + c.offset_m[0], xn * self.depth + c.offset_m[1]
        jacobian = np.empty(vc.shape + (2, 3))
        eps = 1e-5
        for k in range(3):
            moved = []
            for sign in (1.0, -1.0):
                df, dl, dth = sign * eps * np.eye(3)[k]
                cos, sin = math.cos(dth), math.sin(dth)
                # the fixed ceiling point in the frame of the robot moved by (df, dl) and turned by dth
                f, le = forward - df, left - dl
                moved.append(m.project(cos * f + sin * le, -sin * f + cos * le, self.depth, c.offset_m))
            jacobian[..., 0, k] = (moved[0][0] - moved[1][0]) / (2 * eps)
            jacobian[..., 1, k] = (moved[0][1] - moved[1][1]) / (2 * eps)
        return tile_v, tile_u, jacobian

    def motion_blur(
        self, pose: NDArray[np.float64], previous: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64] | None]:
        """The mid-exposure pose and the image motion ``(tiles_v, tiles_u, 2)`` of each blur tile
        (:func:`envs.sensors.exposure.blur_expose`) over the last ``exposure_s`` of the step from ``previous`` (one
        step earlier) to ``pose``; None without an exposure time.

        Each tile moves as the ceiling point at its centre. The ceiling moves through the image
        opposite to the robot: a forward motion moves it down (+v), a motion to the left moves
        it left (-u, the image being mirrored), alike over the image; a turn moves each point
        along an arc around the image point under the rotation axis, the more the farther from
        it (about 2.7 px at the corners at 0.8 rad/s over 1/60 s), the arc taken as its chord.
        Within a tile the motion is that of its centre: off by at most the turn over the
        exposure times the tile's half-diagonal (0.3 px at 0.8 rad/s over 1/60 s).
        """
        c = self.config
        if c.exposure_s == 0:
            return pose, None
        frac = min(1.0, c.exposure_s / self.dt_s)
        dtheta = (pose[2] - previous[2] + math.pi) % (2 * math.pi) - math.pi
        start = pose - frac * np.array([pose[0] - previous[0], pose[1] - previous[1], dtheta])
        mid = (start + pose) / 2
        cos, sin = math.cos(mid[2]), math.sin(mid[2])
        dx, dy = pose[0] - start[0], pose[1] - start[1]
        step = np.array([cos * dx + sin * dy, -sin * dx + cos * dy, pose[2] - start[2]])
        return mid, self._tile_jacobian @ step

    def observe(self, state: WorldState, rng: np.random.Generator) -> tuple[NDArray[np.uint8], dict[str, Any]]:
        c = self.config
        pose = state.robot_pose
        if self._fresh:
            self.seed_noise(rng)
            self._phase = float(rng.uniform(0.0, 2 * math.pi))  # where in its flicker the light starts
            if c.daylight_cct_k[1] > 0:  # from a child stream: the other draws stay as they are
                self.daylight_k = float(rng.spawn(1)[0].uniform(*c.daylight_cct_k))
            self._fresh = False
        rendered = self._steps % c.period_steps == 0
        if rendered:
            offset = int(rng.integers(_NOISE_POOL)) if c.noise_std > 0 else None
            heads = state.positions[self._rows] if c.head_height_m > 0 else None
            self._image, _ = self.render(
                pose, heads, self.channel_gains(pose, state.time_s, self._phase), offset, previous=self._previous_pose
            )
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
