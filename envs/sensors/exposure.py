"""The ceiling camera's exposure of a frame in one pass (:class:`envs.sensors.ceiling_camera.CeilingCamera`):
motion blur by a line kernel per tile, the illumination gain of each channel, vignetting,
pixel noise, and the sensor's saturation at 255."""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import NDArray


@numba.njit(cache=True, error_model="numpy", boundscheck=False)
def blur_expose(
    image: NDArray[np.uint8],
    pad: int,
    tile_v: NDArray[np.int64],
    tile_u: NDArray[np.int64],
    motion: NDArray[np.float64],
    vignette: NDArray[np.float32],
    gain: NDArray[np.float64],
    noise: NDArray[np.float32],
    glare: NDArray[np.float32],
    glare_rows: tuple[int, int],
    out: NDArray[np.uint8],
) -> None:
    """The motion blur, illumination gain, vignetting, glare and noise of a frame, in one pass.

    ``image`` is the sharp frame with a replicated border of ``pad`` pixels. The frame is cut
    into tiles, rows ``tile_v[i]:tile_v[i + 1]`` by columns ``tile_u[j]:tile_u[j + 1]``; tile
    ``(i, j)`` is blurred by the line kernel of ``motion[i, j]`` (:func:`splat_line`; ``pad``
    must exceed its reach), then ``out = saturate(round(blurred * (vignette * gain[c]) + noise))``
    (``vignette`` and ``noise``: flat in ``out``'s order; ``gain``: ``(3,)``, channel ``c``'s). The kernel's weights are in 256ths
    (the blurred value is exact to under a grey level; a sharp one is exact). ``glare`` (empty: none) is
    light added to the sharp frame, flat in ``image``'s order and on its scale, but unbounded
    (:func:`envs.sensors.glare.glare_image`): blurred with it and added before the gain, so only the
    sensor's saturation at 255 clips it; only the output rows ``glare_rows`` ``[first, end)`` take it
    (those within the kernel's reach of a lit row).
    """
    width = out.shape[1]
    tiles = tile_u.shape[0] - 1
    flat_in, flat_out = image.reshape(-1), out.reshape(-1)
    row_in = (width + 2 * pad) * 3
    half = np.float32(0.5)
    g = np.empty(3 * width, dtype=np.float32)  # each channel's gain along a row, in the kernel's 256ths
    for e in range(3 * width):
        g[e] = np.float32(gain[e % 3] / 256.0)
    kernel = np.zeros((2 * pad + 1, 2 * pad + 1), dtype=np.float64)
    offsets = np.empty((tiles, kernel.size), dtype=np.int64)
    weights = np.empty((tiles, kernel.size), dtype=np.uint16)
    taps = np.empty(tiles, dtype=np.int64)
    acc = np.empty(3 * width, dtype=np.uint16)
    lit = glare.shape[0] > 0
    acc_glare = np.zeros(3 * width, dtype=np.float32)
    for i in range(tile_v.shape[0] - 1):
        for j in range(tiles):
            taps[j] = splat_line(motion[i, j, 0], motion[i, j, 1], kernel, row_in, offsets[j], weights[j])
        j = 0
        while j < tiles:  # a run of tiles with one kernel (all of them without a turn) is done at once
            n, end = taps[j], j + 1
            while (
                end < tiles
                and taps[end] == n
                and (offsets[end, :n] == offsets[j, :n]).all()
                and (weights[end, :n] == weights[j, :n]).all()
            ):
                end += 1
            u0, count = tile_u[j], 3 * (tile_u[end] - tile_u[j])
            for v in range(tile_v[i], tile_v[i + 1]):
                row_lit = lit and glare_rows[0] <= v < glare_rows[1]
                first = (v + pad) * row_in + (u0 + pad) * 3
                # slices: their indices are known to be >= 0, which lets the loops vectorize
                for e in range(count):
                    acc[e] = 0
                for k in range(n):
                    w, src = weights[j, k], flat_in[first + offsets[j, k] : first + offsets[j, k] + count]
                    for e in range(count):
                        acc[e] += w * np.uint16(src[e])
                if row_lit:
                    for e in range(count):
                        acc_glare[e] = 0.0
                    for k in range(n):
                        wf, light = np.float32(weights[j, k]), glare[first + offsets[j, k] : first + offsets[j, k] + count]
                        for e in range(count):
                            acc_glare[e] += wf * light[e]
                at = (v * width + u0) * 3
                vig, noi, dst = vignette[at : at + count], noise[at : at + count], flat_out[at : at + count]
                gains = g[3 * u0 : 3 * u0 + count]
                if row_lit:
                    for e in range(count):
                        value = (np.float32(acc[e]) + acc_glare[e]) * (vig[e] * gains[e]) + noi[e] + half
                        dst[e] = 0 if value <= 0.0 else (255 if value >= 255.0 else np.uint8(value))
                else:
                    for e in range(count):
                        value = np.float32(acc[e]) * (vig[e] * gains[e]) + noi[e] + half
                        dst[e] = 0 if value <= 0.0 else (255 if value >= 255.0 else np.uint8(value))
            j = end


@numba.njit(cache=True, error_model="numpy", boundscheck=False)
def splat_line(
    du: float, dv: float, kernel: NDArray[np.float64], row: int, offsets: NDArray[np.int64], weights: NDArray[np.uint16]
) -> int:
    """The line kernel of a motion of ``(du, dv)`` pixels over the exposure, as taps.

    Under half a pixel it is the identity. Otherwise samples along the segment, one per tenth
    of a pixel, are splatted bilinearly into ``kernel`` (square, odd, zero on entry and left
    so), centred on the segment's midpoint, so the blurred image keeps the sharp one's position
    at mid-exposure. Its nonzero entries are written as flat offsets (``row`` elements a pixel
    row, 3 a pixel) and weights in 256ths that sum to 256; returns their count.
    """
    length = math.hypot(du, dv)
    if length < 0.5:
        offsets[0], weights[0] = 0, 256
        return 1
    half = (kernel.shape[0] - 1) // 2
    steps = max(1, int(math.ceil(10 * length)))
    for s in range(steps + 1):
        t = s / steps - 0.5
        x, y = half + t * du, half + t * dv
        x0, y0 = int(math.floor(x)), int(math.floor(y))
        fx, fy = x - x0, y - y0
        kernel[y0, x0] += (1 - fx) * (1 - fy)
        kernel[y0, x0 + 1] += fx * (1 - fy)
        kernel[y0 + 1, x0] += (1 - fx) * fy
        kernel[y0 + 1, x0 + 1] += fx * fy
    scale = 256.0 / kernel.sum()
    taps, total, largest = 0, 0, 0
    for r in range(kernel.shape[0]):
        for c in range(kernel.shape[1]):
            w = int(round(kernel[r, c] * scale))
            kernel[r, c] = 0.0
            if w > 0:
                offsets[taps], weights[taps] = (r - half) * row + (c - half) * 3, w
                if w > weights[largest]:
                    largest = taps
                total += w
                taps += 1
    weights[largest] += 256 - total  # the rounding's remainder: the weights sum to 256
    return taps
