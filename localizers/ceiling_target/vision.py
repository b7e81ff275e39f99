"""The ceiling-target paper's image pipeline (Fukaya et al.), on RGB images of an upward camera.

1. RGB to HSV with the paper's formulas (:func:`paper_hsv`; the pipeline uses OpenCV's
   8-bit ``RGB2HSV_FULL``, which equals them after scaling, as a test shows);
2. per colour, a threshold box learned from labelled images (:func:`fit_colour_range`);
3. the line C: the largest blob of its colour, fitted by least squares; its direction gives
   the rotation;
4. the end squares A and B: found with a 5 x 5 square mask next to the line's ends;
5. camera to world coordinates with the map positions of A and B (:func:`sight_target`).

Everything here works on plain arrays and the camera's metadata (no env objects), so it runs
on a real camera's frames too.

**Camera frame** (the sensor's, ``envs.sensors.ceiling_camera``): a camera looking up sees the
ceiling mirrored. Image right (+u) is the robot's left, image up (-v) its forward direction.
A pixel at ``(u, v)`` (pixel centres at integer + 0.5) sees the ceiling point
``forward = -(v - cy) d / fy + offset_forward``, ``left = (u - cx) d / fx + offset_left`` in
the robot frame, ``d`` the ceiling's height above the camera (with ``undistort`` the
normalized coordinates are corrected for the lens first). The paper's printed transform,
``X_R = X_A - x_A cos(theta) + y_A sin(theta)``, ``Y_R = Y_A - x_A sin(theta) + y_A cos(theta)``,
is this robot-frame relation ``R = P_A - Rot(theta) p_A`` written with a camera y axis that
points the other way (the mirror): ``p_A = (x_A, -y_A)``.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import cv2
import numba
import numpy as np
from numpy.typing import NDArray

from core.geometry import undistort, wrap_angle
from core.schema import check
from localizers.base import MeasurementError

Triple = tuple[float, float, float]


def paper_hsv(rgb: NDArray[Any]) -> NDArray[np.float64]:
    """HSV of RGB values ``(..., 3)`` in ``[0, 1]`` by the paper's formulas, each channel in ``[0, 1]``.

    ``V = max(R, G, B)``; ``V = 0``: ``S = 0`` and H undefined (0 here); else, with
    ``v = min(R, G, B)``, ``S = (V - v) / V`` and ``H = (G - B) / (V - v)`` when R is the
    maximum, ``2 + (B - R) / (V - v)`` when G is, ``4 + (R - G) / (V - v)`` when B is; then
    ``H / 6``, plus 1 when below 0. A grey (``V = v``) has ``S = 0`` and H undefined (0).
    """
    c = np.asarray(rgb, dtype=np.float64)
    r, g, b = c[..., 0], c[..., 1], c[..., 2]
    value = np.max(c, axis=-1)
    low = np.min(c, axis=-1)
    span = value - low
    with np.errstate(divide="ignore", invalid="ignore"):
        sat = np.where(value > 0, span / np.where(value > 0, value, 1.0), 0.0)
        safe = np.where(span > 0, span, 1.0)
        hue = np.where(r == value, (g - b) / safe, np.where(g == value, 2.0 + (b - r) / safe, 4.0 + (r - g) / safe))
    hue = np.where(span > 0, hue / 6.0, 0.0)
    hue = np.where(hue < 0, hue + 1.0, hue)
    return np.stack([hue, sat, value], axis=-1)


def hsv8(image: NDArray[np.uint8]) -> NDArray[np.uint8]:
    """OpenCV's 8-bit HSV of an RGB image: H over the full byte (paper's H times 256), S and V times 255."""
    return np.asarray(cv2.cvtColor(image, cv2.COLOR_RGB2HSV_FULL))


@dataclass(frozen=True)
class ColourRange:
    """The learned threshold box of one colour, in the paper's units.

    ``hsv_lo`` and ``hsv_hi``: H, S, V in ``[0, 1]``; an H range with ``lo > hi`` wraps
    through 0 (red). ``rgb_lo`` and ``rgb_hi``: R, G, B in ``[0, 255]``, the plain RGB box the
    paper's choice of HSV is compared against.
    """

    hsv_lo: Triple
    hsv_hi: Triple
    rgb_lo: Triple = (0.0, 0.0, 0.0)
    rgb_hi: Triple = (255.0, 255.0, 255.0)

    def __post_init__(self) -> None:
        for name in ("hsv_lo", "hsv_hi"):
            value = getattr(self, name)
            check(all(0.0 <= v <= 1.0 for v in value), f"ColourRange.{name} must lie in [0, 1], got {value}")
        for i, channel in ((1, "S"), (2, "V")):
            check(self.hsv_lo[i] <= self.hsv_hi[i], f"ColourRange: {channel} range {self.hsv_lo[i]}..{self.hsv_hi[i]} is empty")
        for name in ("rgb_lo", "rgb_hi"):
            value = getattr(self, name)
            check(all(0.0 <= v <= 255.0 for v in value), f"ColourRange.{name} must lie in [0, 255], got {value}")
        check(
            all(lo <= hi for lo, hi in zip(self.rgb_lo, self.rgb_hi)),
            f"ColourRange: RGB box {self.rgb_lo}..{self.rgb_hi} is empty",
        )

    def mask(self, hsv: NDArray[np.uint8], rgb: NDArray[np.uint8], space: str = "hsv") -> NDArray[np.uint8]:
        """``(H, W)`` uint8 mask (255 inside) of the pixels of an image inside this range."""
        if space == "rgb":
            lo, hi = self._bounds["rgb"]
            return np.asarray(cv2.inRange(rgb, lo, hi))
        boxes = self._bounds["hsv"]
        out = cv2.inRange(hsv, *boxes[0])
        if len(boxes) > 1:  # a hue range through 0: two boxes
            out = cv2.bitwise_or(out, cv2.inRange(hsv, *boxes[1]))
        return np.asarray(out)

    @property
    def _bounds(self) -> dict[str, Any]:
        """The byte bounds of :meth:`mask` (computed once per range)."""
        cached = self.__dict__.get("_byte_bounds")
        if cached is None:
            s_v_lo = [_byte(self.hsv_lo[1] * 255, math.floor), _byte(self.hsv_lo[2] * 255, math.floor)]
            s_v_hi = [_byte(self.hsv_hi[1] * 255, math.ceil), _byte(self.hsv_hi[2] * 255, math.ceil)]
            h_lo, h_hi = _byte(self.hsv_lo[0] * 256, math.floor), _byte(self.hsv_hi[0] * 256, math.ceil)
            if self.hsv_lo[0] <= self.hsv_hi[0]:
                hsv = [(np.array([h_lo, *s_v_lo], np.uint8), np.array([h_hi, *s_v_hi], np.uint8))]
            else:
                hsv = [
                    (np.array([h_lo, *s_v_lo], np.uint8), np.array([255, *s_v_hi], np.uint8)),
                    (np.array([0, *s_v_lo], np.uint8), np.array([h_hi, *s_v_hi], np.uint8)),
                ]
            rgb = (_bytes(self.rgb_lo, 1.0, math.floor), _bytes(self.rgb_hi, 1.0, math.ceil))
            cached = {"hsv": hsv, "rgb": rgb}
            object.__setattr__(self, "_byte_bounds", cached)
        return cached


def _byte(x: float, rounding: Any) -> int:
    return int(min(255, max(0, rounding(x))))


def _bytes(values: Sequence[float], scale: float, rounding: Any) -> NDArray[np.uint8]:
    return np.array([_byte(v * scale, rounding) for v in values], dtype=np.uint8)


def fit_colour_range(
    hsv_pixels: NDArray[np.floating[Any]],
    rgb_pixels: NDArray[np.floating[Any]],
    coverage: float = 0.995,
    margin: float = 0.02,
    hue_margin: float = 0.005,
) -> ColourRange:
    """The threshold box that holds ``coverage`` of a colour's labelled pixels, widened by a margin.

    Args:
        hsv_pixels: ``(n, 3)`` the colour's pixels in the paper's HSV (``[0, 1]``).
        rgb_pixels: ``(n, 3)`` the same pixels in RGB (``[0, 255]``).
        coverage: the share of the pixels inside the box on each channel (central quantiles).
        margin: added on each side of S, V and the RGB channels, in the channel's unit over its range.
        hue_margin: the same for H (of a turn): a hue's spread is small and its neighbours are near
            (an exit sign's green), so it gets a narrower margin.

    Hue is circular: its quantiles are taken of the offsets from the circular mean, so a red
    that straddles 0 gets a wrapping range (``lo > hi``).
    """
    hsv = np.asarray(hsv_pixels, dtype=np.float64).reshape(-1, 3)
    rgb = np.asarray(rgb_pixels, dtype=np.float64).reshape(-1, 3)
    if hsv.shape[0] < 10 or rgb.shape != hsv.shape:
        raise ValueError(f"fit_colour_range needs at least 10 pixels in both spaces, got {hsv.shape[0]} and {rgb.shape[0]}")
    q = (1.0 - coverage) / 2
    angle = 2 * np.pi * hsv[:, 0]
    mean = math.atan2(float(np.mean(np.sin(angle))), float(np.mean(np.cos(angle)))) / (2 * np.pi)
    offsets = (hsv[:, 0] - mean + 0.5) % 1.0 - 0.5
    h_lo, h_hi = np.quantile(offsets, [q, 1 - q])
    h_lo, h_hi = h_lo - hue_margin, h_hi + hue_margin
    if h_hi - h_lo >= 1.0:
        hue = (0.0, 1.0)
    else:
        hue = ((mean + h_lo) % 1.0, (mean + h_hi) % 1.0)
    s_lo, s_hi = np.clip(np.quantile(hsv[:, 1], [q, 1 - q]) + [-margin, margin], 0.0, 1.0)
    v_lo, v_hi = np.clip(np.quantile(hsv[:, 2], [q, 1 - q]) + [-margin, margin], 0.0, 1.0)
    rgb_lo = np.clip(np.quantile(rgb, q, axis=0) - margin * 255, 0.0, 255.0)
    rgb_hi = np.clip(np.quantile(rgb, 1 - q, axis=0) + margin * 255, 0.0, 255.0)
    return ColourRange(
        (float(hue[0]), float(s_lo), float(v_lo)),
        (float(hue[1]), float(s_hi), float(v_hi)),
        (float(rgb_lo[0]), float(rgb_lo[1]), float(rgb_lo[2])),
        (float(rgb_hi[0]), float(rgb_hi[1]), float(rgb_hi[2])),
    )


@dataclass(frozen=True)
class CameraIntrinsics:
    """What the pipeline needs of the camera (its metadata, plain numbers)."""

    width_px: int
    height_px: int
    fx_px: float
    fy_px: float
    cx_px: float
    cy_px: float
    k1: float
    depth_m: float  # the ceiling's height above the camera
    offset_m: tuple[float, float]  # (forward, left) of the camera from the robot's centre

    @staticmethod
    def from_metadata(meta: Mapping[str, Any]) -> CameraIntrinsics:
        """From a ceiling camera's metadata (``fx_px``, ..., ``ceiling_height_m``, ``mount_height_m``)."""
        try:
            return CameraIntrinsics(
                int(meta["width_px"]),
                int(meta["height_px"]),
                float(meta["fx_px"]),
                float(meta["fy_px"]),
                float(meta["cx_px"]),
                float(meta["cy_px"]),
                float(meta["k1"]),
                float(meta["ceiling_height_m"]) - float(meta["mount_height_m"]),
                (float(meta["offset_m"][0]), float(meta["offset_m"][1])),
            )
        except KeyError as exc:
            raise MeasurementError(f"ceiling camera metadata lacks {exc.args[0]!r} (has {', '.join(meta)})") from None

    def to_robot(
        self, points_px: NDArray[np.floating[Any]], undistort_points: bool = False, metres_per_px: float = 0.0
    ) -> NDArray[np.float64]:
        """``(n, 2)`` pixel points ``(u, v)`` -> ceiling points ``(forward, left)`` in the robot frame.

        ``metres_per_px > 0``: the paper's single calibration constant (pixels times a
        proportionality constant), no lens model; else the intrinsics, with the lens
        distortion removed (:func:`core.geometry.undistort`) when ``undistort_points``.
        """
        p = np.asarray(points_px, dtype=np.float64).reshape(-1, 2)
        if metres_per_px > 0:
            left = (p[:, 0] - self.cx_px) * metres_per_px
            forward = -(p[:, 1] - self.cy_px) * metres_per_px
        else:
            xn = (p[:, 0] - self.cx_px) / self.fx_px
            yn = (p[:, 1] - self.cy_px) / self.fy_px
            if undistort_points and self.k1 != 0.0:
                xn, yn = undistort(xn, yn, self.k1)
            left = xn * self.depth_m
            forward = -yn * self.depth_m
        return np.stack([forward + self.offset_m[0], left + self.offset_m[1]], axis=1)


@dataclass(frozen=True)
class TargetMap:
    """The targets a localizer knows (a ceiling feature's map data), as arrays.

    ``codes[i] = (A, B, C)`` colour names; ``a_xy``, ``b_xy`` ``(T, 2)`` the squares' centres.
    """

    names: tuple[str, ...]
    codes: tuple[tuple[str, str, str], ...]
    a_xy: NDArray[np.float64]
    b_xy: NDArray[np.float64]
    end_size_m: float
    line_length_m: float

    @staticmethod
    def from_map_data(data: Mapping[str, Any]) -> TargetMap:
        targets = list(data.get("targets", ()))
        return TargetMap(
            tuple(str(t["name"]) for t in targets),
            tuple((str(t["a"]), str(t["b"]), str(t["c"])) for t in targets),
            np.asarray([t["a_xy"] for t in targets], dtype=np.float64).reshape(-1, 2),
            np.asarray([t["b_xy"] for t in targets], dtype=np.float64).reshape(-1, 2),
            float(data["end_size_m"]),
            float(data["line_length_m"]),
        )

    @property
    def colours(self) -> set[str]:
        return {c for code in self.codes for c in code}


@dataclass(frozen=True)
class Sighting:
    """One target seen in one image, and the robot pose it implies.

    Attributes:
        target: index into the :class:`TargetMap`; ``name`` its name.
        pose: ``(3,)`` the robot pose ``(x, y, theta)`` in the world.
        ends: which squares were found: ``"AB"``, ``"A"`` or ``"B"``.
        line_px: pixels of the line; ``rotation_rad``: the line's direction A -> B in the robot frame.
        a_px, b_px: the squares' centres in the image (NaN when not found).
        line_ends_px: the fitted line's extreme points in the image, ``((u0, v0), (u1, v1))``.
    """

    target: int
    name: str
    pose: NDArray[np.float64]
    ends: str
    line_px: int
    rotation_rad: float
    a_px: tuple[float, float]
    b_px: tuple[float, float]
    line_ends_px: tuple[tuple[float, float], tuple[float, float]]


@dataclass(frozen=True)
class PipelineSettings:
    """The pipeline's numbers (the localizer's parameters hand them over)."""

    colour_space: str = "hsv"
    mask_px: int = 5  # the paper's square mask for the end squares
    mask_fill: float = 0.5  # share of the mask that must be of the end's colour
    min_line_fraction: float = 0.4  # a line blob needs this share of a whole line's expected pixels
    undistort: bool = False
    metres_per_px: float = 0.0  # > 0: the paper's single calibration constant


@dataclass(frozen=True)
class _Blob:
    points: NDArray[np.float64]  # (n, 2) pixel centres (u, v)
    centre: NDArray[np.float64]
    direction: NDArray[np.float64]  # unit, image frame
    ends: tuple[NDArray[np.float64], NDArray[np.float64]]  # the line's extreme points along its direction


def check_image(image: Any, intrinsics: CameraIntrinsics, source: str) -> NDArray[np.uint8]:
    """The image as a C-contiguous uint8 ``(H, W, 3)`` array, or :class:`MeasurementError` naming the problem."""
    a = np.asarray(image)
    want = (intrinsics.height_px, intrinsics.width_px, 3)
    if a.shape != want or a.dtype != np.uint8:
        raise MeasurementError(f"{source}: expected a uint8 image of shape {want}, got {a.dtype} {a.shape}")
    return np.ascontiguousarray(a)


def _line_blobs(mask: NDArray[np.uint8], min_px: int) -> list[_Blob]:
    """The blobs of a line colour large enough to be a line, each with its least-squares direction."""
    if cv2.countNonZero(mask) < min_px:  # most frames: no line of this colour in view
        return []
    # the components of the box around the colour's pixels only (a line is a few percent of the frame): they
    # are the whole mask's, numbered in the same order when the box starts on an even row and column (OpenCV
    # labels 8-connected components by 2 x 2 blocks, in the blocks' raster order)
    bu, bv, bw, bh = cv2.boundingRect(mask)
    bw, bh, bu, bv = bw + bu % 2, bh + bv % 2, bu - bu % 2, bv - bv % 2
    count, labels, stats, _ = cv2.connectedComponentsWithStats(mask[bv : bv + bh, bu : bu + bw], connectivity=8)
    out = []
    for k in range(1, count):
        if stats[k, cv2.CC_STAT_AREA] < min_px:
            continue
        x0, y0, w, h = (int(stats[k, i]) for i in (cv2.CC_STAT_LEFT, cv2.CC_STAT_TOP, cv2.CC_STAT_WIDTH, cv2.CC_STAT_HEIGHT))
        rows, cols = np.nonzero(labels[y0 : y0 + h, x0 : x0 + w] == k)
        pts = np.stack([cols + (x0 + bu) + 0.5, rows + (y0 + bv) + 0.5], axis=1).astype(np.float64)
        centre, direction = fit_line(pts)
        t = (pts - centre) @ direction
        out.append(_Blob(pts, centre, direction, (centre + t.min() * direction, centre + t.max() * direction)))
    return out


def fit_line(points: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Least-squares line through ``(n, 2)`` points (orthogonal distances): its centroid and unit direction."""
    centre = points.mean(axis=0)
    d = points - centre
    cov = d.T @ d
    # the principal axis of the scatter: the direction minimizing the squared orthogonal distances
    angle = 0.5 * math.atan2(2 * cov[0, 1], cov[0, 0] - cov[1, 1])
    return centre, np.array([math.cos(angle), math.sin(angle)])


def _find_end(
    mask_of: Any,
    at: NDArray[np.float64],
    outward: NDArray[np.float64],
    end_px: float,
    settings: PipelineSettings,
    shape: tuple[int, int],
) -> NDArray[np.float64] | None:
    """The centre of an end square of one colour just beyond the line's extreme ``at``, or None.

    ``mask_of(window)`` gives the colour's mask in an image window; the paper's square mask
    (``mask_px`` x ``mask_px``) slides over it and the best-filled place counts if at least
    ``mask_fill`` of the mask is of the colour; the centre is the centroid of the colour's
    pixels around that place (the square's).
    """
    h, w = shape
    guess = at + outward * end_px / 2
    half = int(math.ceil(1.5 * end_px)) + settings.mask_px
    u0, v0 = max(0, int(guess[0]) - half), max(0, int(guess[1]) - half)
    u1, v1 = min(w, int(guess[0]) + half + 1), min(h, int(guess[1]) + half + 1)
    if u1 - u0 < settings.mask_px or v1 - v0 < settings.mask_px:
        return None
    window = (mask_of((slice(v0, v1), slice(u0, u1))) > 0).astype(np.float32)
    k = settings.mask_px
    fill = cv2.boxFilter(window, -1, (k, k), normalize=True, borderType=cv2.BORDER_CONSTANT)
    _, best, _, (bu, bv) = cv2.minMaxLoc(fill)
    if best < settings.mask_fill:
        return None
    # the centroid of the colour's pixels around the best place: the whole square (it is a
    # little larger than the mask, so the mask's own pixels would pull toward the mask's corner)
    r = int(math.ceil(0.75 * end_px)) + 1
    sub = window[max(0, bv - r) : bv + r + 1, max(0, bu - r) : bu + r + 1]
    rows, cols = np.nonzero(sub)
    centre = np.array([cols.mean() + max(0, bu - r) + u0 + 0.5, rows.mean() + max(0, bv - r) + v0 + 0.5])
    # the square must sit at this end of the line: not farther than a square and a mask from it
    if float(np.hypot(*(centre - guess))) > end_px + k:
        return None
    # and lie wholly in the image: a square cut by the border has a biased centroid
    reach = end_px * math.sqrt(0.5) + 1.0
    if not (reach <= centre[0] <= w - reach and reach <= centre[1] <= h - reach):
        return None
    return centre


def sight_targets(
    image: NDArray[np.uint8],
    intrinsics: CameraIntrinsics,
    targets: TargetMap,
    ranges: Mapping[str, ColourRange],
    settings: PipelineSettings,
) -> list[list[Sighting]]:
    """Every line blob in ``image`` that can be read as a target, with each reading it allows.

    Returns one list per line blob: the :class:`Sighting` of every target (and orientation)
    whose colour code fits the blob's line and end colours; a list of several is ambiguous
    (the caller picks by its estimate).
    """
    hsv = hsv8(image) if settings.colour_space == "hsv" else image
    rgb = image
    h, w = image.shape[:2]
    mpp = settings.metres_per_px if settings.metres_per_px > 0 else intrinsics.depth_m / intrinsics.fx_px
    end_px = targets.end_size_m / mpp
    line_px = targets.line_length_m / mpp * targets.end_size_m / mpp  # a whole line's pixel count
    min_px = max(4, int(settings.min_line_fraction * line_px))
    results: list[list[Sighting]] = []
    line_colours = sorted({code[2] for code in targets.codes})
    end_colours = sorted({c for code in targets.codes for c in code[:2]})
    for line_colour in line_colours:
        mask = ranges[line_colour].mask(hsv, rgb, settings.colour_space)
        for blob in _line_blobs(mask, min_px):
            found: dict[int, dict[str, NDArray[np.float64]]] = {0: {}, 1: {}}
            for side, at in enumerate(blob.ends):
                outward = blob.direction * (1.0 if side == 1 else -1.0)
                for colour in end_colours:
                    rng = ranges[colour]

                    def mask_of(window: tuple[slice, slice], rng: ColourRange = rng) -> NDArray[np.uint8]:
                        return rng.mask(
                            np.ascontiguousarray(hsv[window]), np.ascontiguousarray(rgb[window]), settings.colour_space
                        )

                    centre = _find_end(mask_of, at, outward, end_px, settings, (h, w))
                    if centre is not None:
                        found[side][colour] = centre
            readings = _readings(blob, found, line_colour, intrinsics, targets, settings)
            if readings:
                results.append(readings)
    return results


def _readings(
    blob: _Blob,
    found: Mapping[int, Mapping[str, NDArray[np.float64]]],
    line_colour: str,
    intrinsics: CameraIntrinsics,
    targets: TargetMap,
    settings: PipelineSettings,
) -> list[Sighting]:
    """The sightings of every target and orientation consistent with the ends found at the blob's two sides."""
    out = []
    line_robot = intrinsics.to_robot(blob.points, settings.undistort, settings.metres_per_px)
    centre_r, direction_r = fit_line(line_robot)
    for t, (a, b, c) in enumerate(targets.codes):
        if c != line_colour:
            continue
        for a_side in (0, 1):
            b_side = 1 - a_side
            a_px = found[a_side].get(a)
            b_px = found[b_side].get(b)
            if a_px is None and b_px is None:
                continue
            # an end of another colour at a side rules this orientation out
            if (a_px is None and found[a_side]) or (b_px is None and found[b_side]):
                continue
            ends_px = [p for p in (a_px, b_px) if p is not None]
            ends_r = intrinsics.to_robot(np.array(ends_px), settings.undistort, settings.metres_per_px)
            # orient the fitted direction from A toward B
            if a_px is not None and b_px is not None:
                toward_b = ends_r[1] - ends_r[0]
            elif a_px is not None:
                toward_b = centre_r - ends_r[0]
            else:
                toward_b = ends_r[0] - centre_r
            d = direction_r if float(direction_r @ toward_b) >= 0 else -direction_r
            world_ab = targets.b_xy[t] - targets.a_xy[t]
            theta = float(wrap_angle(math.atan2(world_ab[1], world_ab[0]) - math.atan2(d[1], d[0])))
            c_t, s_t = math.cos(theta), math.sin(theta)
            rot = np.array([[c_t, -s_t], [s_t, c_t]])
            positions = []
            if a_px is not None:
                positions.append(targets.a_xy[t] - rot @ ends_r[0])
            if b_px is not None:
                positions.append(targets.b_xy[t] - rot @ ends_r[-1])
            xy = np.mean(positions, axis=0)
            nan = (math.nan, math.nan)
            out.append(
                Sighting(
                    t,
                    targets.names[t],
                    np.array([xy[0], xy[1], theta]),
                    ("A" if a_px is not None else "") + ("B" if b_px is not None else ""),
                    int(blob.points.shape[0]),
                    float(math.atan2(d[1], d[0])),
                    nan if a_px is None else (float(a_px[0]), float(a_px[1])),
                    nan if b_px is None else (float(b_px[0]), float(b_px[1])),
                    ((float(blob.ends[0][0]), float(blob.ends[0][1])), (float(blob.ends[1][0]), float(blob.ends[1][1]))),
                )
            )
    return out


def colour_ranges(values: Mapping[str, ColourRange], needed: Iterable[str], source: str) -> dict[str, ColourRange]:
    """The ranges of the colours ``needed``, or a :class:`ValueError` naming a colour without one."""
    missing = sorted(set(needed) - set(values))
    if missing:
        raise ValueError(f"{source}: no learned threshold for colour(s) {', '.join(missing)} (have: {', '.join(sorted(values))})")
    return {name: values[name] for name in needed}


# ---------------------------------------------------------------------------- the ceiling plan (ours)
@dataclass(frozen=True)
class CeilingPlan:
    """The white parts of the ceiling as built (a ceiling feature's ``plan`` map data), for the lost test.

    The light panels, ``light_half_m`` (across, along) half sizes, repeat every ``light_pitch_m``
    along y at ``x = light_x_m`` from ``light_first_y_m`` on; ``rects`` ``(n, 4)`` are the other white
    rectangles (the exit signs' lettering) as ``(x, y, half across, half along)``.
    """

    light_pitch_m: float
    light_first_y_m: float
    light_x_m: float
    light_half_m: tuple[float, float]
    rects: NDArray[np.float64]

    @staticmethod
    def from_map_data(data: Mapping[str, Any]) -> CeilingPlan | None:
        """From a ceiling feature's map data; None when it holds no plan."""
        plan = data.get("plan")
        if plan is None:
            return None
        lights = plan["lights"]
        rects = [(s["x_m"], s["y_m"], s["text_size_m"][0] / 2, s["text_size_m"][1] / 2) for s in plan.get("signs", ())]
        return CeilingPlan(
            float(lights["pitch_m"]),
            float(lights["first_y_m"]),
            float(lights["x_m"]),
            (float(lights["size_m"][0]) / 2, float(lights["size_m"][1]) / 2),
            np.asarray(rects, dtype=np.float64).reshape(-1, 4),
        )

    def white_distance(self, xy: NDArray[np.float64]) -> NDArray[np.float64]:
        """Signed distance (m) of the world points ``xy`` ``(n, 2)`` to the nearest white rectangle
        (negative inside)."""
        dy = xy[:, 1] - self.light_first_y_m
        dy = dy - self.light_pitch_m * np.round(dy / self.light_pitch_m)  # to the nearest panel's centre
        best = _rect_distance(xy[:, 0] - self.light_x_m, dy, *self.light_half_m)
        for x, y, hx, hy in self.rects:
            best = np.minimum(best, _rect_distance(xy[:, 0] - x, xy[:, 1] - y, hx, hy))
        return best


@numba.njit(cache=True)
def _rect_distance(dx: NDArray[np.float64], dy: NDArray[np.float64], hx: float, hy: float) -> NDArray[np.float64]:
    """Signed distance (m) of points ``(dx, dy)`` from a rectangle's centre to the rectangle of half sizes ``(hx, hy)``."""
    out = np.empty(dx.shape[0])
    for i in range(dx.shape[0]):
        ox, oy = abs(dx[i]) - hx, abs(dy[i]) - hy
        out[i] = max(ox, oy) if ox <= 0.0 and oy <= 0.0 else math.hypot(max(ox, 0.0), max(oy, 0.0))
    return out


@dataclass(frozen=True)
class PlanSettings:
    """The lost test's numbers (the localizer's ``plan_*`` parameters hand them over)."""

    cell_px: int = 4  # the image is averaged over cells of this many pixels a side
    white_saturation: float = 0.03  # a cell of at most this HSV saturation is white (a light panel)
    plain_saturation: tuple[float, float] = (0.035, 0.15)  # a cell in this range shows the off-white ceiling
    min_value: float = 90.0  # cells darker than this (0-255) say nothing: heads, hair, shadows
    margin_out_m: float = 0.2  # white farther than this from the plan's white is unexplained
    margin_in_m: float = 0.08  # cells this far inside the plan's white are expected white


@dataclass(frozen=True)
class PlanEvidence:
    """What one image says of a pose against the ceiling plan (areas in m^2 of ceiling).

    Attributes:
        unexplained_m2: white seen more than ``margin_out_m`` from every white of the plan.
        expected_m2: the plan's white, ``margin_in_m`` inside its edges, in view (not darkened).
        missing_m2: of that, what shows plain ceiling.
        matched_m2: white seen inside the plan's white.
    """

    unexplained_m2: float
    expected_m2: float
    missing_m2: float
    matched_m2: float


def cell_points(intrinsics: CameraIntrinsics, cell_px: int) -> NDArray[np.float64]:
    """The robot-frame ceiling points ``(rows * cols, 2)`` of the centres of the image's cells of
    ``cell_px`` pixels (lens distortion removed), in the order of :func:`cell_tint`'s arrays."""
    rows, cols = intrinsics.height_px // cell_px, intrinsics.width_px // cell_px
    u, v = np.meshgrid((np.arange(cols) + 0.5) * cell_px, (np.arange(rows) + 0.5) * cell_px)
    return intrinsics.to_robot(np.stack([u.ravel(), v.ravel()], axis=1), undistort_points=True)


def cell_tint(image: NDArray[np.uint8], cell_px: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """HSV saturation and value (0-255) of the image averaged over cells of ``cell_px`` pixels, flat.

    The saturation does not change with the illumination's gain or the lens's vignetting (both
    scale R, G and B alike), which is why a white light panel stands out of the off-white ceiling
    by it wherever it is in the image; averaging the cells takes the pixel noise down.
    """
    h, w = image.shape[0] // cell_px, image.shape[1] // cell_px
    small = cv2.resize(image[: h * cell_px, : w * cell_px], (w, h), interpolation=cv2.INTER_AREA).astype(np.float64)
    r, g, b = small[:, :, 0], small[:, :, 1], small[:, :, 2]
    value = np.maximum(np.maximum(r, g), b)  # over the channels pairwise: numpy reduces a last axis of 3 slowly
    saturation = (value - np.minimum(np.minimum(r, g), b)) / np.maximum(value, 1.0)
    return saturation.ravel(), value.ravel()


def plan_evidence(
    plan: CeilingPlan,
    pose: NDArray[np.float64],
    points: NDArray[np.float64],
    tint: tuple[NDArray[np.float64], NDArray[np.float64]],
    cell_m2: float,
    settings: PlanSettings,
) -> PlanEvidence:
    """Compare the white cells of an image (:func:`cell_tint`, :func:`cell_points`) with the plan
    seen from ``pose``. Dark cells (a head under the camera) count neither way: what is hidden is
    neither missing nor unexplained."""
    c, s = math.cos(float(pose[2])), math.sin(float(pose[2]))
    xy = np.stack([pose[0] + c * points[:, 0] - s * points[:, 1], pose[1] + s * points[:, 0] + c * points[:, 1]], axis=1)
    distance = plan.white_distance(xy)
    saturation, value = tint
    lit = value >= settings.min_value
    white = lit & (saturation <= settings.white_saturation)
    plain = lit & (saturation >= settings.plain_saturation[0]) & (saturation <= settings.plain_saturation[1])
    inside = distance <= -settings.margin_in_m
    return PlanEvidence(
        float(np.count_nonzero(white & (distance > settings.margin_out_m))) * cell_m2,
        float(np.count_nonzero(inside & lit)) * cell_m2,
        float(np.count_nonzero(inside & plain)) * cell_m2,
        float(np.count_nonzero(white & (distance <= 0.0))) * cell_m2,
    )
