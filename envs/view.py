"""The top view's geometry, without pygame: frame size and scale, and the window that follows
the robot in a world too large for one frame (``view_m``).

:mod:`envs.render` draws with it; :mod:`envs.config` checks a world's ``view_m`` with it when
the world is loaded (a view so small that the follow mode's background would be huge).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from envs.config import WorldConfig

FRAME_LONG_SIDE_PX = 600
#: the narrowest frame: a tall, narrow world (a corridor) is drawn centred in a frame this wide, so
#: that the caption line (world, time, crowd, the localizer's state: about 330 px) has room; every
#: shipped world's frame is at least this wide anyway
MIN_FRAME_WIDTH_PX = 320
MARGIN_PX = 16
CAPTION_PX = 20
#: in follow mode the background reaches this far beyond the drawn bounds (a wall's width, labels)
BACKGROUND_PAD_PX = 40
#: the longest side of the follow mode's background (the whole world at the view's scale)
MAX_BACKGROUND_PX = 8000

Bounds = tuple[float, float, float, float]


@dataclass(frozen=True)
class FrameLayout:
    """A frame that shows a region of ``span_x`` x ``span_y`` metres: pixels per metre, the frame's
    width and height (even: H.264 in yuv420p, what RecordVideo writes, rejects odd ones), and the
    pixel column and row of the region's top left corner (a margin around, the caption above)."""

    scale: float
    width: int
    height: int
    left: float
    top: float


def fit(span_x: float, span_y: float) -> FrameLayout:
    """The frame of about :data:`FRAME_LONG_SIDE_PX` on its long side that shows ``span_x`` x ``span_y`` m,
    at least :data:`MIN_FRAME_WIDTH_PX` wide (the region centred)."""
    scale = min(
        (FRAME_LONG_SIDE_PX - 2 * MARGIN_PX) / span_x,
        (FRAME_LONG_SIDE_PX - 2 * MARGIN_PX - CAPTION_PX) / span_y,
    )
    width = max(MIN_FRAME_WIDTH_PX, 2 * math.ceil((span_x * scale + 2 * MARGIN_PX) / 2))
    height = 2 * math.ceil((span_y * scale + 2 * MARGIN_PX + CAPTION_PX) / 2)
    left = (width - span_x * scale) / 2
    top = CAPTION_PX + (height - CAPTION_PX - span_y * scale) / 2
    return FrameLayout(scale, width, height, left, top)


def drawn_bounds(config: WorldConfig) -> Bounds:
    """``(xmin, ymin, xmax, ymax)`` the top view covers: the arena, the extra walls and the landmarks."""
    xs = [config.arena_m[0], config.arena_m[2]]
    ys = [config.arena_m[1], config.arena_m[3]]
    for x1, y1, x2, y2 in config.walls:
        xs += [x1, x2]
        ys += [y1, y2]
    for lm in config.landmarks:
        xs.append(lm.x_m)
        ys.append(lm.y_m)
    return (min(xs), min(ys), max(xs), max(ys))


def background_size_px(bounds: Bounds, scale: float) -> tuple[int, int]:
    """``(width, height)`` of the follow mode's background: the bounds at ``scale`` and the pad."""
    xmin, ymin, xmax, ymax = bounds
    return (
        math.ceil((xmax - xmin) * scale) + 2 * BACKGROUND_PAD_PX,
        math.ceil((ymax - ymin) * scale) + 2 * BACKGROUND_PAD_PX,
    )


def follow_window(centre_xy: tuple[float, float], view_m: tuple[float, float], bounds: Bounds) -> tuple[float, float]:
    """Lower left corner ``(x0, y0)`` of the ``view_m`` window centred on ``centre_xy`` and moved
    to stay inside ``bounds``; along an axis on which the bounds are narrower than the window, the
    window is centred on them."""
    corner = []
    for centre, size, lo, hi in zip(centre_xy, view_m, bounds[:2], bounds[2:]):
        if hi - lo <= size:
            corner.append(0.5 * (lo + hi) - 0.5 * size)
        else:
            corner.append(min(max(centre - 0.5 * size, lo), hi - size))
    return (corner[0], corner[1])
