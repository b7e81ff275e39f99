"""The stereo paper's image side (paper D): vertical edges of one camera's image, typed.

1. :func:`vertical_edge_response`: the paper's tall ``m x n`` filter (101 x 7 at 640 x 480,
   :func:`filter_size` scales it) at up to 5 detection rows, in each colour channel;
2. :func:`detect_edges`: thresholded local maxima of the response with sub-pixel position;
   each edge gets one of 30 *types* (channel x level x polarity, :func:`edge_type`; the
   counts are :mod:`localizers.base`'s ``EDGE_*`` constants);
3. :class:`EdgeDetector` bundles one camera's filter, rows and threshold;
   :func:`draw_detections` marks the edges on the image like the paper's Fig. 2.

The three cameras' edges are matched and triangulated in :mod:`envs.stereo.matching`;
:mod:`envs.stereo.vision` gathers both. Everything here works on plain arrays (no env
objects), so it runs on a real camera's frames too: uint8 RGB images of shape ``(H, W, 3)``.

**Pixel coordinates** (shared with the renderer and the geometric fast mode): the continuous
column coordinate ``u`` runs left to right; pixel column ``k`` spans ``[k, k + 1)`` and its
centre, ``k + 0.5``, is where its viewing ray passes: ``u = cx + f X / Z`` for a point at
``X`` right of and ``Z`` ahead of the camera (so an image of width ``W`` whose optical axis
is at its middle has ``cx = W / 2``). A colour boundary between columns ``k`` and ``k + 1``
is at ``u = k + 1``. Filter responses are indexed by column: index ``k`` is the filter
centred on column ``k``'s centre. An ideal step at ``u = k + 1`` gives a response plateau
at indices ``k`` and ``k + 1``; its edge is reported at ``u = k + 1``. Rows are integer
pixel indices (row 0 at the top).

**Errors.** Bad parameters raise ValueError naming the argument and the value; malformed
measured data (images, edge lists) raise :class:`~localizers.base.MeasurementError` (a
ValueError) naming it; bad config dataclasses raise
:class:`~core.schema.ConfigError` (a ValueError).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, NamedTuple

import cv2
import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

from core.schema import check, is_int, is_real
from core.types import EDGE_CHANNELS as CHANNELS  # R, G, B
from core.types import EDGE_LEVELS as LEVELS  # detection rows; level 0 is the topmost
from core.types import EDGE_POLARITIES as POLARITIES  # rising, falling
from core.types import EDGE_TYPES, MeasurementError

# The paper's filter at its cameras' 640 x 480.
PAPER_FILTER_ROWS = 101
PAPER_FILTER_COLS = 7
PAPER_WIDTH_PX = 640
PAPER_HEIGHT_PX = 480

# draw_detections: marker colours (RGB) of the channels R, G, B
CHANNEL_COLOURS = ((255, 0, 0), (0, 255, 0), (0, 0, 255))

# ---------------------------------------------------------------------------------------
# Argument checks shared by the stereo modules
# ---------------------------------------------------------------------------------------


def shown(value: Any) -> Any:
    """A value as error messages show it: numpy scalars as Python numbers (``nan``, not ``np.float64(nan)``)."""
    return value.item() if isinstance(value, np.generic) else value


def finite_array(values: ArrayLike, name: str) -> NDArray[np.float64]:
    """``values`` as float64, or ValueError naming ``name`` and the first value that is not a finite number."""
    try:
        a = np.asarray(values, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be numbers, got {values!r}") from None
    if not np.isfinite(a).all():
        raise ValueError(f"{name} must be finite, got {shown(a[~np.isfinite(a)].ravel()[0])!r}")
    return a


# ---------------------------------------------------------------------------------------
# Edge types
# ---------------------------------------------------------------------------------------


def _in_range_int(value: Any, name: str, count: int) -> int:
    if not is_int(value) or not 0 <= int(value) < count:
        raise ValueError(f"{name} must be an integer in 0..{count - 1}, got {shown(value)!r}")
    return int(value)


def _falling_flag(value: Any) -> bool:
    if not (isinstance(value, bool | np.bool_) or (is_int(value) and int(value) in (0, 1))):
        raise ValueError(f"falling must be a bool, got {shown(value)!r}")
    return bool(value)


def edge_type(channel: int, level: int, falling: bool) -> int:
    """The type ``6 level + 2 channel + falling`` (0..29) of an edge.

    Args:
        channel: 0 = R, 1 = G, 2 = B.
        level: the detection row's index, 0 the topmost.
        falling: True when the pixel value decreases from left to right.
    """
    c = _in_range_int(channel, "channel", CHANNELS)
    lv = _in_range_int(level, "level", LEVELS)
    return POLARITIES * CHANNELS * lv + POLARITIES * c + int(_falling_flag(falling))


def edge_type_parts(t: int) -> tuple[int, int, bool]:
    """``(channel, level, falling)`` of the edge type ``t`` (the inverse of :func:`edge_type`)."""
    t = _in_range_int(t, "edge type", EDGE_TYPES)
    return (t % (POLARITIES * CHANNELS)) // POLARITIES, t // (POLARITIES * CHANNELS), bool(t % POLARITIES)


def _int_array(values: ArrayLike, name: str, count: int) -> NDArray[np.int64]:
    """``values`` as int64, or ValueError naming the first value that is not an integer in ``0..count - 1``.

    Integer dtypes only (no floats, no bools); an empty array of any dtype is accepted.
    """
    a = np.asarray(values)
    if a.size == 0:
        return a.astype(np.int64)
    if a.dtype.kind not in "iu":
        flat = a.ravel()
        bad = flat[0]
        if a.dtype.kind in "fc":
            off = ~np.isfinite(flat) | (flat != np.round(flat))
            if off.any():
                bad = flat[np.argmax(off)]
        raise ValueError(f"{name} must be integers in 0..{count - 1}, got {shown(bad)!r} (dtype {a.dtype})")
    outside = (a < 0) | (a >= count)
    if outside.any():
        raise ValueError(f"{name} {shown(a[outside].ravel()[0])!r} is outside 0..{count - 1}")
    return a.astype(np.int64)


def check_edge_types(types: ArrayLike, where: str) -> NDArray[np.int64]:
    """``types`` as an int64 array, or ValueError naming ``where`` and the first bad value.

    A type must be an integer (integer dtype; no floats, no bools) in ``0..29``. An empty
    array of any dtype is accepted.
    """
    return _int_array(types, f"{where}: edge type", EDGE_TYPES)


def edge_types(channel: ArrayLike, level: ArrayLike, falling: ArrayLike) -> NDArray[np.int64]:
    """:func:`edge_type` on arrays (broadcast): int64 types of the shape of the broadcast inputs."""
    c = _int_array(channel, "edge_types: channel", CHANNELS)
    lv = _int_array(level, "edge_types: level", LEVELS)
    f = np.asarray(falling)
    if f.size and f.dtype != np.bool_ and not (f.dtype.kind in "iu" and np.isin(f, (0, 1)).all()):
        raise ValueError(f"edge_types: falling must be bools, got {shown(f.ravel()[0])!r} (dtype {f.dtype})")
    return np.asarray(POLARITIES * CHANNELS * lv + POLARITIES * c + f.astype(np.int64), dtype=np.int64)


def edge_types_parts(types: ArrayLike) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.bool_]]:
    """:func:`edge_type_parts` on an array: ``(channel, level, falling)`` arrays of its shape."""
    t = check_edge_types(types, "edge_types_parts")
    return (t % (POLARITIES * CHANNELS)) // POLARITIES, t // (POLARITIES * CHANNELS), (t % POLARITIES).astype(np.bool_)


# ---------------------------------------------------------------------------------------
# The filter
# ---------------------------------------------------------------------------------------


def _nearest_odd(x: float) -> int:
    """The odd integer nearest to ``x`` (a tie, ``x`` even, goes up)."""
    return 2 * math.floor(x / 2.0) + 1


def filter_size(width_px: int, height_px: int) -> tuple[int, int]:
    """``(rows, cols)`` of the paper's 101 x 7 filter (at 640 x 480) scaled to an image size.

    ``rows`` is the odd integer nearest to ``101 height_px / 480``, ``cols`` the one nearest
    to ``7 width_px / 640`` (ties go up), each at least 3: ``(101, 7)`` at 640 x 480,
    ``(51, 3)`` at 320 x 240, ``(203, 15)`` at 1280 x 960.
    """
    for name, value in (("width_px", width_px), ("height_px", height_px)):
        if not is_int(value) or value <= 0:
            raise ValueError(f"filter_size: {name} must be a positive integer, got {shown(value)!r}")
    rows = _nearest_odd(PAPER_FILTER_ROWS * height_px / PAPER_HEIGHT_PX)
    cols = _nearest_odd(PAPER_FILTER_COLS * width_px / PAPER_WIDTH_PX)
    return max(3, rows), max(3, cols)


def check_rgb_image(image: Any, where: str) -> NDArray[np.uint8]:
    """The image as a C-contiguous uint8 ``(H, W, 3)`` array, or MeasurementError naming its dtype and shape."""
    a = np.asarray(image)
    if a.dtype != np.uint8 or a.ndim != 3 or a.shape[2] != 3 or a.shape[0] == 0 or a.shape[1] == 0:
        raise MeasurementError(f"{where}: expected a uint8 RGB image of shape (H, W, 3), got {a.dtype} {a.shape}")
    return np.ascontiguousarray(a)


def _check_filter_side(value: Any, name: str) -> int:
    if not is_int(value) or value < 3 or value % 2 == 0:
        raise ValueError(f"{name} must be an odd integer >= 3, got {shown(value)!r}")
    return int(value)


def check_rows(rows: ArrayLike, height_px: int, filter_rows: int, where: str) -> NDArray[np.int64]:
    """The detection rows as int64 ``(L,)``, or ValueError naming the bad row.

    1 to 5 strictly increasing integer rows (level 0 the topmost), each with its filter
    window ``rows[l] -+ (filter_rows - 1) / 2`` inside ``0..height_px - 1``.
    """
    r = np.asarray(rows)
    if r.ndim != 1 or not 1 <= r.size <= LEVELS:
        raise ValueError(f"{where}: rows must be 1 to {LEVELS} detection rows, got {r.tolist()!r}")
    if r.dtype.kind not in "iu":
        raise ValueError(f"{where}: rows must be integers, got {r.tolist()!r}")
    r = r.astype(np.int64)
    if r.size > 1 and not (np.diff(r) > 0).all():
        raise ValueError(f"{where}: rows must increase strictly (level 0 is the topmost), got {r.tolist()!r}")
    half = filter_rows // 2
    for row in r:
        if row - half < 0 or row + half > height_px - 1:
            raise ValueError(
                f"{where}: the {filter_rows}-row window of row {int(row)} does not fit an image of {height_px} rows "
                f"(rows {half}..{height_px - 1 - half} do)"
            )
    return r


@numba.njit(cache=True)
def _response_kernel(
    image: NDArray[np.uint8], rows: NDArray[np.int64], half_rows: int, half_cols: int, out: NDArray[np.float32]
) -> None:
    """The filter of :func:`vertical_edge_response` into the zeroed ``out`` ``(L, W, 3)``."""
    height, width, _ = image.shape
    flat = image.reshape(height, width * 3)
    sums = np.empty(width * 3, dtype=np.int32)
    denom = np.float32(half_cols * (2 * half_rows + 1))
    for lv in range(rows.shape[0]):
        # per-column sums over the window's rows (a loop over contiguous bytes: it vectorizes)
        sums[:] = 0
        for r in range(rows[lv] - half_rows, rows[lv] + half_rows + 1):
            line = flat[r]
            for j in range(width * 3):
                sums[j] += line[j]
        # sliding sums of the half_cols columns left and right of each column u
        for c in range(3):
            left = np.int64(0)
            right = np.int64(0)
            for j in range(half_cols):
                left += sums[3 * j + c]
                right += sums[3 * (half_cols + 1 + j) + c]
            for u in range(half_cols, width - half_cols):
                out[lv, u, c] = np.float32(right - left) / denom
                if u + half_cols + 1 < width:
                    left += sums[3 * u + c] - sums[3 * (u - half_cols) + c]
                    right += sums[3 * (u + half_cols + 1) + c] - sums[3 * (u + 1) + c]


def vertical_edge_response(image: ArrayLike, rows: ArrayLike, filter_rows: int, filter_cols: int) -> NDArray[np.float32]:
    """The paper's vertical-edge filter at each detection row, in each colour channel.

    For detection row ``rows[l]`` and column ``u``: over the ``filter_rows`` rows centred on
    the detection row, the mean of the ``(filter_cols - 1) / 2`` columns right of ``u`` minus
    the mean of as many columns left of it (the centre column has weight 0). A step of
    ``delta`` (right minus left, 0-255) spanning the whole window gives ``delta``; one spanning
    a share ``q`` of the window's rows gives ``q delta``. Columns within
    ``(filter_cols - 1) / 2`` of the border get 0.

    Args:
        image: ``(H, W, 3)`` uint8 RGB.
        rows: ``(L,)`` 1 to 5 strictly increasing detection rows (level 0 the topmost), each
            window inside the image.
        filter_rows: odd, >= 3 (the paper's ``m``; :func:`filter_size`).
        filter_cols: odd, >= 3, at most ``W`` (the paper's ``n``).

    Returns:
        ``(L, W, 3)`` float32: the response per level, column and channel.
    """
    img = check_rgb_image(image, "vertical_edge_response: image")
    fr = _check_filter_side(filter_rows, "vertical_edge_response: filter_rows")
    fc = _check_filter_side(filter_cols, "vertical_edge_response: filter_cols")
    height, width, _ = img.shape
    if fc > width:
        raise ValueError(f"vertical_edge_response: filter_cols {fc} exceeds the image width {width}")
    r = check_rows(rows, height, fr, "vertical_edge_response")
    out = np.zeros((r.size, width, 3), dtype=np.float32)
    _response_kernel(img, r, fr // 2, fc // 2, out)
    return out


# ---------------------------------------------------------------------------------------
# Edges
# ---------------------------------------------------------------------------------------


class EdgeList(NamedTuple):
    """Edges detected in one image, sorted by ``(type, u)``.

    Attributes:
        u: ``(N,)`` float64 continuous column (sub-pixel; see the module's pixel convention).
        type: ``(N,)`` int64 edge type (:func:`edge_type`).
        strength: ``(N,)`` float32 ``|response|`` at the peak (0-255 units).
    """

    u: NDArray[np.float64]
    type: NDArray[np.int64]
    strength: NDArray[np.float32]


def empty_edges() -> EdgeList:
    """An :class:`EdgeList` without edges."""
    return EdgeList(np.empty(0, np.float64), np.empty(0, np.int64), np.empty(0, np.float32))


def _sort_edges(u: NDArray[np.float64], t: NDArray[np.int64], s: NDArray[np.float32]) -> EdgeList:
    if u.size > 1 and not _is_sorted(t, u):
        order = np.lexsort((u, t))
        u, t, s = u[order], t[order], s[order]
    return EdgeList(u, t, s)


def _is_sorted(t: NDArray[np.int64], u: NDArray[np.float64]) -> bool:
    dt = np.diff(t)
    return bool(((dt > 0) | ((dt == 0) & (np.diff(u) >= 0))).all())


def check_edges(edges: EdgeList, where: str) -> EdgeList:
    """``edges`` with checked dtypes, sorted by ``(type, u)``, or MeasurementError naming the bad value.

    ``u`` must be finite, ``type`` in ``0..29``, ``strength`` finite and >= 0, all 1-D of one length.
    """
    try:
        u, t, s = edges
    except (TypeError, ValueError):
        raise MeasurementError(f"{where}: expected an EdgeList (u, type, strength), got {type(edges).__name__}") from None
    try:
        u = np.asarray(u, dtype=np.float64)
        s = np.asarray(s, dtype=np.float32)
    except (TypeError, ValueError):
        raise MeasurementError(f"{where}: edge u and strength must be numbers, got {u!r} and {s!r}") from None
    try:
        t = check_edge_types(t, where)
    except ValueError as exc:
        raise MeasurementError(str(exc)) from None
    if u.ndim != 1 or t.shape != u.shape or s.shape != u.shape:
        raise MeasurementError(f"{where}: u, type and strength must be 1-D of one length, got {u.shape}, {t.shape}, {s.shape}")
    if not np.isfinite(u).all():
        raise MeasurementError(f"{where}: edge column u must be finite, got {shown(u[~np.isfinite(u)][0])!r}")
    bad = ~np.isfinite(s) | (s < 0)
    if bad.any():
        raise MeasurementError(f"{where}: edge strength must be finite and >= 0, got {shown(s[bad][0])!r}")
    return _sort_edges(u, t, s)


def concat_edges(*lists: EdgeList) -> EdgeList:
    """The edges of several lists (checked) in one, sorted by ``(type, u)``."""
    checked = [check_edges(e, f"concat_edges: list {i}") for i, e in enumerate(lists)]
    if not checked:
        return empty_edges()
    return _sort_edges(
        np.concatenate([e.u for e in checked]),
        np.concatenate([e.type for e in checked]),
        np.concatenate([e.strength for e in checked]),
    )


@numba.njit(cache=True)
def _detect_kernel(
    response: NDArray[np.float32], threshold: float, border: int,
    u_out: NDArray[np.float64], t_out: NDArray[np.int64], s_out: NDArray[np.float32],
) -> int:  # fmt: skip
    """Peaks of :func:`detect_edges` into the ``*_out`` arrays (in ``(type, u)`` order); returns their count."""
    levels, width, _ = response.shape
    lo = border  # the first and last columns whose response is known
    hi = width - 1 - border
    v = np.empty(width, dtype=np.float32)
    n = 0
    for lv in range(levels):
        for c in range(3):
            for falling in range(2):
                sign = np.float32(-1.0) if falling else np.float32(1.0)
                for i in range(width):
                    v[i] = max(sign * response[lv, i, c], np.float32(0.0))
                t = 6 * lv + 2 * c + falling
                i = lo + 1
                while i <= hi - 1:
                    if v[i] < threshold or v[i] <= v[i - 1]:
                        i += 1
                        continue
                    j = i  # the run of equal values (a plateau) starting at i
                    while j + 1 <= hi and v[j + 1] == v[i]:
                        j += 1
                    if j + 1 <= hi and v[j + 1] < v[i]:
                        y0 = float(v[i - 1])
                        y1 = float(v[i])
                        y2 = float(v[j + 1])
                        s = 0.5 * (j - i) + 1.0  # the parabola's sample spacing: neighbours to the plateau's centre
                        curv = y0 + y2 - 2.0 * y1  # < 0: both neighbours are below the peak
                        off = s * (y0 - y2) / (2.0 * curv)
                        off = min(0.5, max(-0.5, off))
                        u_out[n] = 0.5 * (i + j) + 0.5 + off  # + 0.5: index k is centred on u = k + 0.5
                        t_out[n] = t
                        s_out[n] = v[i]
                        n += 1
                    i = j + 1
    return n


def detect_edges(response: ArrayLike, threshold: float, *, border_px: int = 0) -> EdgeList:
    """Edges: the local maxima of ``|response|`` along ``u`` that reach ``threshold``.

    Per level and channel, rising (``response > 0``) and falling (``response < 0``) edges are
    the peaks of the positive and negative parts of the response. A peak is a sample, or a
    run of equal samples (a plateau, counted once at its centre), whose two neighbours are
    strictly smaller. Its position is refined by a parabola through the peak (the plateau's
    centre) and its two neighbours, the offset clipped to ``+-0.5`` px. With the module's
    pixel convention an ideal step at ``u = k + 1`` is found at ``u = k + 1``, and a step
    blurred over one pixel (an anti-aliased boundary) exactly at its sub-pixel position.

    Args:
        response: ``(L, W, 3)`` the :func:`vertical_edge_response`, ``L <= 5``.
        threshold: the least ``|response|`` of an edge (0-255 units), finite and > 0.
        border_px: columns at each side whose response is not known (the filter's
            ``(filter_cols - 1) / 2``): a peak needs both its neighbours inside the rest.

    Returns:
        The :class:`EdgeList`, sorted by ``(type, u)``; ``strength`` is the peak's ``|response|``.
    """
    r = np.asarray(response)
    if r.ndim != 3 or r.shape[2] != CHANNELS or not 1 <= r.shape[0] <= LEVELS:
        raise ValueError(f"detect_edges: response must have shape (L, W, 3) with 1 <= L <= {LEVELS}, got {r.shape}")
    if r.dtype.kind not in "fiu":
        raise ValueError(f"detect_edges: response must be numeric, got dtype {r.dtype}")
    r = np.ascontiguousarray(r, dtype=np.float32)
    if not np.isfinite(r).all():
        raise ValueError(f"detect_edges: response must be finite, got {shown(r[~np.isfinite(r)][0])!r}")
    if not is_real(threshold):
        raise ValueError(f"detect_edges: threshold must be a number, got {shown(threshold)!r}")
    if not (math.isfinite(threshold) and threshold > 0):
        raise ValueError(f"detect_edges: threshold must be finite and > 0, got {shown(threshold)!r}")
    if not is_int(border_px) or border_px < 0:
        raise ValueError(f"detect_edges: border_px must be an integer >= 0, got {shown(border_px)!r}")
    return find_edges(r, float(threshold), int(border_px))


def find_edges(response: NDArray[np.float32], threshold: float, border_px: int) -> EdgeList:
    """:func:`detect_edges` without its input checks, for a caller that made ``response`` itself
    (contiguous float32 ``(L, W, 3)``, finite; the stereo camera's fast mode, every frame)."""
    levels, width, _ = response.shape
    cap = levels * CHANNELS * POLARITIES * (width // 2 + 1)  # peaks are at least 2 samples apart
    u = np.empty(cap, np.float64)
    t = np.empty(cap, np.int64)
    s = np.empty(cap, np.float32)
    n = _detect_kernel(response, threshold, border_px, u, t, s)
    return EdgeList(u[:n].copy(), t[:n].copy(), s[:n].copy())


# ---------------------------------------------------------------------------------------
# One camera's detector and drawing
# ---------------------------------------------------------------------------------------


@dataclass(frozen=True)
class EdgeDetector:
    """One camera's edge detection: the filter, its detection rows and the threshold.

    ``rows``: 1 to 5 strictly increasing detection rows (level 0 the topmost);
    ``filter_rows``, ``filter_cols``: odd, >= 3 (:func:`filter_size`); ``threshold``: the least
    ``|response|`` of an edge (0-255 units).
    """

    rows: tuple[int, ...]
    filter_rows: int = PAPER_FILTER_ROWS
    filter_cols: int = PAPER_FILTER_COLS
    threshold: float = 20.0

    def __post_init__(self) -> None:
        check(
            1 <= len(self.rows) <= LEVELS and all(is_int(r) and r >= 0 for r in self.rows),
            f"EdgeDetector.rows must be 1 to {LEVELS} rows >= 0, got {self.rows!r}",
        )
        check(
            all(a < b for a, b in zip(self.rows, self.rows[1:])), f"EdgeDetector.rows must increase strictly, got {self.rows!r}"
        )
        for name in ("filter_rows", "filter_cols"):
            value = getattr(self, name)
            check(
                is_int(value) and value >= 3 and value % 2 == 1,
                f"EdgeDetector.{name} must be an odd integer >= 3, got {shown(value)!r}",
            )
        check(
            is_real(self.threshold, finite=True) and self.threshold > 0,
            f"EdgeDetector.threshold must be finite and > 0, got {shown(self.threshold)!r}",
        )

    @staticmethod
    def for_image(width_px: int, height_px: int, rows: Sequence[int], threshold: float = 20.0) -> EdgeDetector:
        """The detector with the paper's filter scaled to the image size (:func:`filter_size`)."""
        fr, fc = filter_size(width_px, height_px)
        return EdgeDetector(tuple(int(r) for r in rows), fr, fc, threshold)

    def response(self, image: ArrayLike) -> NDArray[np.float32]:
        """``(L, W, 3)`` :func:`vertical_edge_response` of an image."""
        return vertical_edge_response(image, self.rows, self.filter_rows, self.filter_cols)

    def detect(self, image: ArrayLike) -> EdgeList:
        """The image's edges (:func:`detect_edges`, the filter's border excluded)."""
        return detect_edges(self.response(image), self.threshold, border_px=self.filter_cols // 2)


def draw_detections(
    image: ArrayLike, edges_or_matches_u: ArrayLike, types: ArrayLike, rows: ArrayLike, *, radius_px: int = 4
) -> NDArray[np.uint8]:
    """A copy of ``image`` with detections marked like the paper's Fig. 2.

    A white line across each detection row; a circle at ``(u, rows[level])`` of each
    detection in its channel's colour (red, green, blue), hollow for a rising and filled for
    a falling edge. ``u`` follows the module's pixel convention (drawn sub-pixel).

    Args:
        image: ``(H, W, 3)`` uint8 RGB (not modified).
        edges_or_matches_u: ``(N,)`` columns (an :class:`EdgeList`'s ``u`` or a camera's ``Matches`` column).
        types: ``(N,)`` their edge types.
        rows: the detector's rows (``rows[level]`` is level ``level``'s row).
        radius_px: the circles' radius (px), >= 1.

    Returns:
        The marked ``(H, W, 3)`` uint8 image.
    """
    out = check_rgb_image(image, "draw_detections: image").copy()
    u = finite_array(edges_or_matches_u, "draw_detections: u")
    t = check_edge_types(types, "draw_detections: types")
    if u.ndim != 1 or t.shape != u.shape:
        raise ValueError(f"draw_detections: u and types must be 1-D of one length, got {u.shape} and {t.shape}")
    r = np.asarray(rows)
    if r.ndim != 1 or r.dtype.kind not in "iu" or not 1 <= r.size <= LEVELS or (r < 0).any() or (r >= out.shape[0]).any():
        raise ValueError(f"draw_detections: rows must be 1 to {LEVELS} rows inside the image, got {r.tolist()!r}")
    if not is_int(radius_px) or radius_px < 1:
        raise ValueError(f"draw_detections: radius_px must be an integer >= 1, got {shown(radius_px)!r}")
    channel, level, falling = edge_types_parts(t)
    if (level >= r.size).any():
        raise ValueError(f"draw_detections: an edge of level {int(level.max())} but only {r.size} rows {r.tolist()!r}")
    out[r, :, :] = 255
    shift = 4  # sub-pixel centres: cv2 draws at coordinates / 2**shift, pixel k's centre at k
    scale = 1 << shift
    for uk, ck, lk, fk in zip(u, channel, level, falling):
        centre = (int(round((uk - 0.5) * scale)), int(r[lk]) * scale)
        cv2.circle(out, centre, int(radius_px) * scale, CHANNEL_COLOURS[ck], -1 if fk else 1, cv2.LINE_8, shift)
    return out
