"""A specular glare spot on the ceiling's glossy fluorescent tape, seen by the upward camera.

**Where the spot is.** The tape lies on the ceiling plane (height ``H``) and the camera looks up
from below it (``d_c = H - z_camera`` under the ceiling). The tape mirrors a lamp at ``(x_L, y_L, z_L)``
like a flat mirror: the camera sees the lamp's mirror image ``(x_L, y_L, 2 H - z_L)``, and the spot is
where the ray from the camera to that image crosses the ceiling, on the line from the camera's
point under the ceiling to the lamp's, at the share ``d_c / (d_c + d_L)`` of the way
(``d_L = H - z_L``; :func:`mirror_spot_xy`). A lamp flush with the ceiling (``d_L = 0``, the corridor's
recessed panels) mirrors onto itself: only a light *below* the ceiling plane can put a spot on the
tape, as lamps hung below the ceiling (pendants), or daylight through a door, a source low and off
to the side. Moving the camera by ``dx`` moves the spot on the ceiling by ``dx d_L / (d_c + d_L)``
and, in the image (which moves with the camera), by ``-dx d_c / (d_c + d_L)`` of ceiling.

**Its shape.** The normalised Blinn-Phong lobe with Schlick's Fresnel factor (T. Akenine-Moeller,
E. Haines, N. Hoffman, Real-Time Rendering, 3rd ed., 2008, section 7.6, eq. 7.49; C. Schlick, "An
inexpensive BRDF model for physically-based rendering", Computer Graphics Forum 13(3), 1994), lit by
each lamp as a point source of luminous intensity ``I``: the tape's specular radiance is
``F(l.h) (n + 8) / (8 pi) (n.h)^n E``, with ``E = I cos(theta_i) / r^2`` the lamp's illuminance on
the tape, ``h`` the half vector between the directions to the lamp and to the camera, ``n`` the
ceiling's normal (down) and ``n`` in the exponent the shininess. A white Lambertian surface of
reflectance 1 under the ceiling's illuminance ``E_c`` has radiance ``E_c / pi`` and shows 255 on the
rendered ceiling's scale, so the spot adds ``255 F(l.h) (n + 8) / 8 (n.h)^n E / E_c`` to each channel
(a dielectric's specular reflection keeps the light's colour: white, under the channel gains like
every pixel). It peaks where ``h`` is the ceiling's normal: at the mirror point. It is added to the
target tape's pixels only (the ceiling's tiles, the signs and the lamps are matte or light themselves,
and heads hide it), before the camera's gain, blur and noise, so the sensor's saturation at 255 is what
clips it: where every channel saturates the tape shows white and its hue is gone
(:func:`envs.sensors.exposure.blur_expose`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np
from numpy.typing import NDArray

from core.schema import check
from envs.features.ceiling import LABEL_COLOUR


@dataclass(frozen=True)
class GlareConfig:
    """The lamps that the ceiling's glossy tape mirrors into the camera, and the tape's gloss.

    Off by default (no lamps: the shipped corridor's panels sit flush with the ceiling). To turn it on, give lamps below the
    ceiling, e.g. the corridor's pendant fluorescent lamps hung 0.5 m below a 2.5 m ceiling over its
    centre line between the panels, ``lamps_m: [[0, 2.4, 2.0], [0, 4.8, 2.0], ...]``; the other fields
    hold their physically sourced values.
    """

    #: the lamps, world (x, y, z) in m, each below the ceiling (none: no glare)
    lamps_m: tuple[tuple[float, float, float], ...] = ()
    #: each lamp's luminous intensity toward the tape, cd: a bare T8 fluorescent tube, 3350 lm (Philips
    #: TL-D 36W/840 datasheet), as a diffuse cylinder (flux = pi^2 I_perpendicular): 340 cd
    lamp_intensity_cd: float = 340.0
    #: the ceiling's mean illuminance, lx, at which a white of reflectance 1 shows 255 (the rendered ceiling's
    #: scale): bare tubes hung below the ceiling send half their 3350 lm up, over the 2 m x 2.4 m of ceiling
    #: per lamp about 350 lx (EN 12464-1:2011, 4.2.3, asks at least 30 lx on a ceiling, 50 lx in offices)
    ceiling_lux: float = 350.0
    #: the Blinn-Phong exponent of the glossy tape: 200 is a Beckmann roughness of 0.1 (a glossy plastic)
    #: by the conversion n = 2 / m^2 - 2 (B. Walter et al., "Microfacet models for refraction through rough
    #: surfaces", EGSR 2007); 100 (m 0.14) to 1000 (m 0.045) spans glossy to near-mirror films
    shininess: float = 200.0
    #: the tape's surface refractive index, for Fresnel's reflectance: PVC, 1.54 (R0 = 0.045 at normal incidence)
    refractive_index: float = 1.54

    def __post_init__(self) -> None:
        where = "ceiling_camera.glare"
        for lamp in self.lamps_m:
            check(len(lamp) == 3, f"{where}.lamps_m: each lamp is [x, y, z] in m, got {list(lamp)}")
        check(self.lamp_intensity_cd > 0, f"{where}.lamp_intensity_cd must be > 0, got {self.lamp_intensity_cd}")
        check(self.ceiling_lux > 0, f"{where}.ceiling_lux must be > 0, got {self.ceiling_lux}")
        check(1 <= self.shininess <= 10_000, f"{where}.shininess must be in [1, 10000], got {self.shininess}")
        check(1 < self.refractive_index <= 3, f"{where}.refractive_index must be in (1, 3], got {self.refractive_index}")

    @property
    def on(self) -> bool:
        """Whether any lamp can put a glare spot on the tape."""
        return len(self.lamps_m) > 0

    def check_ceiling(self, ceiling_m: float, where: str) -> None:
        """Every lamp below the ceiling plane (a lamp at or above it mirrors nothing into the camera)."""
        for lamp in self.lamps_m:
            check(
                0 <= lamp[2] < ceiling_m,
                f"{where}: glare.lamps_m {list(lamp)}: a lamp must hang below the ceiling at {ceiling_m} m (z in [0, {ceiling_m}))",
            )

    @property
    def r0(self) -> float:
        """Fresnel's reflectance at normal incidence, ``((n - 1) / (n + 1))^2``."""
        return ((self.refractive_index - 1) / (self.refractive_index + 1)) ** 2


def mirror_spot_xy(camera_xyz: NDArray[np.float64], lamp_xyz: NDArray[np.float64], ceiling_m: float) -> NDArray[np.float64]:
    """The ceiling point ``(x, y)`` where the camera sees the lamp mirrored (module docstring)."""
    camera_xyz, lamp_xyz = np.asarray(camera_xyz, dtype=np.float64), np.asarray(lamp_xyz, dtype=np.float64)
    d_c, d_l = ceiling_m - camera_xyz[2], ceiling_m - lamp_xyz[2]
    return np.asarray(camera_xyz[:2] + (lamp_xyz[:2] - camera_xyz[:2]) * d_c / (d_c + d_l), dtype=np.float64)


class Glare:
    """A camera's glare spots: the light each target-tape pixel adds (:func:`glare_image`)."""

    def __init__(
        self,
        config: GlareConfig,
        forward: NDArray[np.float32],
        left: NDArray[np.float32],
        depth_m: float,
        ceiling_m: float,
        offset_m: tuple[float, float],
    ) -> None:
        """``forward``, ``left``: every pixel's ray's robot-frame point on the ceiling, ``depth_m`` above the
        camera; the ceiling at ``ceiling_m`` above the floor; the camera at ``offset_m`` from the robot's centre."""
        self.config = config
        self._forward, self._left = forward, left
        self._depth_m = depth_m
        self._offset_m = offset_m
        lamps = np.asarray(config.lamps_m, dtype=np.float64).reshape(-1, 3)
        self._lamps = np.column_stack([lamps[:, :2], ceiling_m - lamps[:, 2]])  # (x, y, depth below the ceiling)

    def camera_xy(self, pose: NDArray[np.float64]) -> NDArray[np.float64]:
        """The camera's world ``(x, y)`` at robot pose ``pose``."""
        cos, sin = math.cos(pose[2]), math.sin(pose[2])
        f, le = self._offset_m
        return np.array([pose[0] + cos * f - sin * le, pose[1] + sin * f + cos * le])

    def image(self, pose: NDArray[np.float64], labels: NDArray[np.uint8]) -> tuple[NDArray[np.float32], int, int] | None:
        """The ``(H, W, 3)`` light the glare adds at ``pose`` on the rendered ceiling's scale (unbounded),
        on the pixels ``labels`` marks as target tape, and the rows ``[first, end)`` that hold any; None
        when no tape is in view."""
        if int(labels.max()) < LABEL_COLOUR:
            return None
        c = self.config
        out = np.zeros(labels.shape + (3,), dtype=np.float32)
        cam = self.camera_xy(pose)
        first, end = glare_image(self._forward, self._left, labels, pose, cam[0], cam[1], self._depth_m, self._lamps,
                                 c.lamp_intensity_cd / c.ceiling_lux, c.shininess, c.r0, out)  # fmt: skip
        return out, first, end


@numba.njit(cache=True, error_model="numpy", boundscheck=False)
def glare_image(
    forward: NDArray[np.float32],
    left: NDArray[np.float32],
    labels: NDArray[np.uint8],
    pose: NDArray[np.float64],
    camera_x: float,
    camera_y: float,
    depth: float,
    lamps: NDArray[np.float64],
    intensity_per_lux: float,
    shininess: float,
    r0: float,
    out: NDArray[np.float32],
) -> tuple[int, int]:
    """Write into ``out`` ``(H, W, 3)`` the glare of every target-tape pixel (label >= ``LABEL_COLOUR``):
    ``255 F(l.h) (n + 8) / 8 (n.h)^n I cos(theta_i) / (r^2 E_c)`` summed over the lamps (module docstring).

    ``lamps`` ``(k, 3)``: each lamp's world ``(x, y)`` and depth below the ceiling; ``intensity_per_lux``:
    ``I / E_c``; the camera at ``(camera_x, camera_y)``, ``depth`` below the ceiling. Returns the rows
    ``[first, end)`` holding the tape's pixels (``(0, 0)``: none).
    """
    cos, sin = math.cos(pose[2]), math.sin(pose[2])
    norm = (shininess + 8.0) / 8.0
    first, end = labels.shape[0], 0
    for v in range(labels.shape[0]):
        for u in range(labels.shape[1]):
            if labels[v, u] < LABEL_COLOUR:
                continue
            first, end = min(first, v), v + 1
            f, le = forward[v, u], left[v, u]
            x, y = pose[0] + cos * f - sin * le, pose[1] + sin * f + cos * le
            # unit vectors from the tape's point toward the camera and the lamp (z up; both point down)
            vx, vy, vz = camera_x - x, camera_y - y, -depth
            vn = math.sqrt(vx * vx + vy * vy + vz * vz)
            total = 0.0
            for k in range(lamps.shape[0]):
                lx, ly, lz = lamps[k, 0] - x, lamps[k, 1] - y, -lamps[k, 2]
                r2 = lx * lx + ly * ly + lz * lz
                ln = math.sqrt(r2)
                hx, hy, hz = vx / vn + lx / ln, vy / vn + ly / ln, vz / vn + lz / ln
                hn = math.sqrt(hx * hx + hy * hy + hz * hz)
                cos_h = -hz / hn  # the half vector against the ceiling's normal (0, 0, -1)
                if cos_h <= 0.0:
                    continue
                cos_d = (lx * hx + ly * hy + lz * hz) / (ln * hn)
                fresnel = r0 + (1.0 - r0) * (1.0 - cos_d) ** 5
                total += fresnel * norm * cos_h**shininess * intensity_per_lux * (-lz / ln) / r2
            value = np.float32(255.0 * total)
            out[v, u, 0] = value
            out[v, u, 1] = value
            out[v, u, 2] = value
    return (first, end) if end > 0 else (0, 0)
