"""Drawing a :class:`~envs.localization_env.LocalizationEnv` as ``rgb_array`` frames or a window.

The frame shows the floor, walls, landmarks (coloured while the camera really sees them,
grey otherwise), the crowd and ball, the true robot pose, what each sensor draws of itself
(a camera's sight lines under the bodies, range sensors' hit points over them) and a
caption (a line, or more where the frame is too narrow for it). Wrappers add their own drawing through
``env.add_overlay(draw)``: every frame calls ``draw(canvas)`` with a :class:`Canvas` whose
methods take world coordinates (metres, y up).

The frame size is fixed per world (:func:`frame_shape`): about 600 px on the long side,
with even width and height so that video encoders accept it. Everything static (floor,
field outline, walls, landmark labels) is drawn once; a frame blits that background and
draws the moving parts. Large point sets (particles, candidates, scans) are written into
the pixel array with numpy instead of one pygame call per mark.

A world too large for one frame sets ``view_m`` (:class:`~envs.config.WorldConfig`): the
frame then shows a window of that many metres (and its margins) centred on the robot's true
position, moved to stay inside the world's bounds. Its background is the whole world drawn
once at the window's scale; each frame blits the part under the window and hands the moving
parts, sensors and overlays a :class:`Canvas` whose origin follows the window, so they draw
in world coordinates, as in a whole-world frame. The geometry (sizes, scales, the window) is :mod:`envs.view`.
"""

from __future__ import annotations

import math
import os
import sys
from collections.abc import Callable, Iterable, Sequence
from typing import TYPE_CHECKING, Any

# before pygame initializes anything: without a display server (Linux servers, CI) the
# window-less "dummy" video driver lets "human" mode run headless; a desktop keeps its real
# driver, and an SDL_VIDEODRIVER set by the user always wins. Nothing here plays sound.
if sys.platform.startswith("linux") and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
    os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")
os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")

import numpy as np  # noqa: E402
import pygame  # noqa: E402
import pygame.surfarray  # noqa: E402
from numpy.typing import ArrayLike, NDArray  # noqa: E402

from core.types import Overlay  # noqa: E402
from envs.config import WorldConfig  # noqa: E402
from envs.palette import HIDDEN_LANDMARK, Color, landmark_color  # noqa: E402
from envs.state import WorldState  # noqa: E402
from envs.view import (  # noqa: E402
    BACKGROUND_PAD_PX,
    CAPTION_PX,
    Bounds,
    background_size_px,
    drawn_bounds,
    fit,
    follow_window,
)

if TYPE_CHECKING:
    from envs.localization_env import LocalizationEnv

_FONT_PX = 16
_CAPTION_LEFT_PX = 6  # where each caption line starts
_LABEL_FONT_PX = 14
_MIN_LANDMARK_PX = 5  # landmark discs are at least this radius so that thin poles show
_DRAW_CALL_LIMIT = 200  # above this many marks, write pixels with numpy instead of pygame.draw
_COORD_LIMIT_PX = 100_000  # pygame.draw takes C ints: clip far-away coordinates to this

BACKGROUND: Color = (40, 40, 40)
FIELD_FLOOR: Color = (46, 120, 60)
FIELD_LINE: Color = (235, 235, 235)
ROOM_FLOOR: Color = (215, 210, 200)
ROOM_OUTLINE: Color = (170, 165, 155)
WALL: Color = (20, 20, 20)
CAPTION_BACKGROUND: Color = (20, 20, 20)
CAPTION_TEXT: Color = (230, 230, 230)
ROBOT_FILL: Color = (250, 250, 250)
ROBOT_OUTLINE: Color = (220, 0, 0)


def _layout(config: WorldConfig) -> tuple[float, Bounds, int, int, float, float]:
    """Scale (px/m), world bounds, frame width and height, and the pixel position of the top left
    corner of what the frame shows: the whole world (its ``(xmin, ymax)``) or the ``view_m`` window."""
    bounds = drawn_bounds(config)
    xmin, ymin, xmax, ymax = bounds
    frame = fit(xmax - xmin, ymax - ymin) if config.view_m is None else fit(*config.view_m)
    return frame.scale, bounds, frame.width, frame.height, frame.left, frame.top


def _panel_heights(config: WorldConfig, width: int) -> list[int]:
    """Per sensor of ``config`` (in its order), the height of the panel it shows under the top
    view in a frame ``width`` wide (a camera's images: :meth:`SensorConfig.panel_height_px`), 0 for none."""
    return [sensor.panel_height_px(width) for sensor in config.sensors.values()]


def frame_shape(config: WorldConfig) -> tuple[int, int, int]:
    """``(H, W, 3)`` of every ``rgb_array`` frame rendered for ``config``: the top view (the window's
    with ``view_m``) and under it the sensors' panels (a stereo camera's images)."""
    _, _, width, height, _, _ = _layout(config)
    return (height + sum(_panel_heights(config, width)), width, 3)


def _font(size_px: int) -> pygame.font.Font:
    if not pygame.font.get_init():
        pygame.font.init()
    return pygame.font.Font(None, size_px)


class Canvas:
    """World-coordinate drawing on one frame, handed to every overlay callable.

    Coordinates are metres in the world frame (y up), angles radians counter-clockwise
    from +x, colours RGB tuples. Rows with a non-finite coordinate (an invalid estimate)
    are not drawn.

    Args:
        surface: the frame being drawn.
        scale_px_per_m: pixels per metre.
        origin_px: pixel position of ``top_left_m``.
        top_left_m: ``(xmin, ymax)``, the top left corner of the drawn world region.
        floor: floor colour, used to shade weighted marks drawn with pygame.
        default_radius_m: radius of :meth:`pose` marks when none is given (the robot's).
    """

    def __init__(
        self,
        surface: pygame.Surface,
        scale_px_per_m: float,
        origin_px: tuple[float, float],
        top_left_m: tuple[float, float],
        floor: Color,
        default_radius_m: float,
    ) -> None:
        self.surface = surface
        self.scale = scale_px_per_m
        self._ox, self._oy = origin_px
        self._xmin, self._ymax = top_left_m
        self.floor = floor
        self.default_radius_m = default_radius_m
        self.captions: list[tuple[str, Color]] = []

    # ------------------------------------------------------------------ mapping
    def to_pixel(self, xy: ArrayLike) -> NDArray[np.int64]:
        """Pixel ``(column, row)`` of world points: ``(2,)`` -> ``(2,)``, ``(n, 2)`` -> ``(n, 2)``."""
        p = np.asarray(xy, dtype=np.float64)
        col = self._ox + (p[..., 0] - self._xmin) * self.scale
        row = self._oy + (self._ymax - p[..., 1]) * self.scale
        out = np.stack([col, row], axis=-1)
        return np.floor(np.clip(out, -_COORD_LIMIT_PX, _COORD_LIMIT_PX)).astype(np.int64)

    def _pt(self, xy: Sequence[float] | NDArray[np.float64]) -> tuple[int, int]:
        """:meth:`to_pixel` of one point, without numpy's per-call overhead (the frame's many small calls)."""
        col = self._ox + (float(xy[0]) - self._xmin) * self.scale
        row = self._oy + (self._ymax - float(xy[1])) * self.scale
        return (
            math.floor(min(max(col, -_COORD_LIMIT_PX), _COORD_LIMIT_PX)),
            math.floor(min(max(row, -_COORD_LIMIT_PX), _COORD_LIMIT_PX)),
        )

    # ------------------------------------------------------------------ primitives
    def line(self, p: ArrayLike, q: ArrayLike, color: Color, width_px: int = 1) -> None:
        """Segment from world point ``p`` to ``q``."""
        a, b = np.asarray(p, dtype=np.float64), np.asarray(q, dtype=np.float64)
        if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
            return
        pygame.draw.line(self.surface, color, self._pt(a), self._pt(b), width_px)

    def circle(self, x: float, y: float, radius_m: float, color: Color, width_px: int = 1) -> None:
        """Circle of ``radius_m`` (at least 1 px) around ``(x, y)``; ``width_px=0`` fills it."""
        if not all(math.isfinite(v) for v in (x, y, radius_m)):
            return
        radius_px = max(1, round(radius_m * self.scale))
        pygame.draw.circle(self.surface, color, self._pt((x, y)), min(radius_px, _COORD_LIMIT_PX), width_px)

    def rect(self, x0: float, y0: float, x1: float, y1: float, color: Color, width_px: int = 0) -> None:
        """Axis-aligned rectangle between world corners ``(x0, y0)`` and ``(x1, y1)``; ``width_px=0`` fills it."""
        (c0, r0), (c1, r1) = self._pt((min(x0, x1), max(y0, y1))), self._pt((max(x0, x1), min(y0, y1)))
        pygame.draw.rect(self.surface, color, pygame.Rect(c0, r0, max(1, c1 - c0), max(1, r1 - r0)), width_px)

    def polygon(self, corners: ArrayLike, color: Color, width_px: int = 0) -> None:
        """Polygon through the world points ``corners`` ``(K, 2)``; ``width_px=0`` fills it."""
        points = [self._pt(c) for c in np.asarray(corners, dtype=np.float64)]
        if len(points) >= 3:
            pygame.draw.polygon(self.surface, color, points, width_px)

    def pose(self, x: float, y: float, theta: float, color: Color, radius_m: float | None = None, width_px: int = 2) -> None:
        """A pose as a circle outline with a heading line from its centre past the rim."""
        if not all(math.isfinite(v) for v in (x, y, theta)):
            return
        r = self.default_radius_m if radius_m is None else radius_m
        self.circle(x, y, r, color, width_px)
        tip = (x + 1.4 * r * math.cos(theta), y + 1.4 * r * math.sin(theta))
        self.line((x, y), tip, color, width_px)

    def points(self, xy: ArrayLike, color: Color, size_px: int = 2) -> None:
        """Square dots of ``size_px`` at world points ``(n, 2)``."""
        p = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        p = p[np.all(np.isfinite(p), axis=1)]
        if p.shape[0] == 0:
            return
        px = self.to_pixel(p)
        offsets = np.arange(size_px) - (size_px - 1) // 2
        dc, dr = np.meshgrid(offsets, offsets, indexing="ij")
        cols = (px[:, 0:1] + dc.reshape(1, -1)).reshape(-1)
        rows = (px[:, 1:2] + dr.reshape(1, -1)).reshape(-1)
        self._write(cols, rows, color, None)

    def poses(self, poses: ArrayLike, weights: ArrayLike | None, color: Color, length_px: int = 6) -> None:
        """Many small pose marks (particles, candidates): a dot and a heading tick of ``length_px`` each.

        Up to a few hundred marks are drawn with pygame; more are written into the pixel
        array in one vectorized step (about 0.6 ms per 1000 marks), blended over the frame by weight.

        Args:
            poses: ``(n, 3)`` world poses.
            weights: ``(n,)`` importances (shading, normalized by their maximum) or ``None``.
            color: full-weight colour.
            length_px: heading tick length.
        """
        q = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
        w = None if weights is None else np.asarray(weights, dtype=np.float64).reshape(-1)
        if w is not None and w.shape[0] != q.shape[0]:
            raise ValueError(f"poses: {q.shape[0]} poses but {w.shape[0]} weights")
        keep = np.all(np.isfinite(q), axis=1)
        q = q[keep]
        if q.shape[0] == 0:
            return
        alpha = None
        if w is not None:
            w = np.nan_to_num(w[keep], nan=0.0, posinf=0.0, neginf=0.0).clip(min=0.0)
            top = w.max()
            alpha = 0.15 + 0.85 * (w / top if top > 0 else np.ones_like(w))
        px = self.to_pixel(q[:, :2])
        if q.shape[0] <= _DRAW_CALL_LIMIT:
            self._poses_with_pygame(px, q[:, 2], alpha, color, length_px)
            return
        steps = np.arange(length_px + 1)
        cols = np.rint(px[:, 0:1] + np.cos(q[:, 2:3]) * steps).astype(np.int64)
        rows = np.rint(px[:, 1:2] - np.sin(q[:, 2:3]) * steps).astype(np.int64)
        # a 2x2 dot at the position on top of the tick
        dot_c = px[:, 0:1] + np.array([[0, 1, 0, 1]])
        dot_r = px[:, 1:2] + np.array([[0, 0, 1, 1]])
        cols = np.concatenate([cols, dot_c], axis=1)
        rows = np.concatenate([rows, dot_r], axis=1)
        a = None if alpha is None else np.repeat(alpha, cols.shape[1])
        self._write(cols.reshape(-1), rows.reshape(-1), color, a)

    def text(self, text: str, color: Color = CAPTION_TEXT) -> None:
        """Append ``text`` to the frame's caption line."""
        self.captions.append((text, color))

    def overlay(self, overlay: Overlay, color: Color) -> None:
        """Draw a localizer's :class:`~localizers.base.Overlay`: poses shaded by weight, points, label."""
        # empty weights mean unweighted; any other count than one per pose is an error in poses()
        weights = overlay.weights if np.asarray(overlay.weights).size else None
        self.poses(overlay.poses, weights, color)
        self.points(overlay.points_xy, color, size_px=2)
        if overlay.label:
            self.text(overlay.label, color)

    # ------------------------------------------------------------------ internals
    def _poses_with_pygame(
        self, px: NDArray[np.int64], theta: NDArray[np.float64], alpha: NDArray[np.float64] | None, color: Color, length_px: int
    ) -> None:
        base = np.asarray(color, dtype=np.float64)
        floor = np.asarray(self.floor, dtype=np.float64)
        for i in range(px.shape[0]):
            c = color if alpha is None else tuple(int(v) for v in np.rint(floor + (base - floor) * alpha[i]))
            start = (int(px[i, 0]), int(px[i, 1]))
            tip = (round(start[0] + length_px * math.cos(theta[i])), round(start[1] - length_px * math.sin(theta[i])))
            pygame.draw.line(self.surface, c, start, tip, 1)
            pygame.draw.circle(self.surface, c, start, 2)

    def _write(self, cols: NDArray[np.int64], rows: NDArray[np.int64], color: Color, alpha: NDArray[np.float64] | None) -> None:
        """Set pixels (blended over what is there by ``alpha`` where given) in one vectorized write."""
        width, height = self.surface.get_size()
        inside = (cols >= 0) & (cols < width) & (rows >= 0) & (rows < height)
        cols, rows = cols[inside], rows[inside]
        if cols.size == 0:
            return
        pixels = pygame.surfarray.pixels2d(self.surface)  # (W, H) packed pixels; a view that locks the surface
        try:
            if alpha is None:
                pixels[cols, rows] = self.surface.map_rgb(color)
                return
            a = alpha[inside].astype(np.float32)
            old = pixels[cols, rows]
            kind = old.dtype.type
            rgb_mask = kind(sum(self.surface.get_masks()[:3]))
            packed = old & ~rgb_mask  # keep whatever else the pixel format stores
            for shift, value in zip(self.surface.get_shifts()[:3], color):
                channel = ((old >> kind(shift)) & kind(0xFF)).astype(np.float32)
                packed |= np.rint(channel + (value - channel) * a).astype(old.dtype) << kind(shift)
            pixels[cols, rows] = packed
        finally:
            del pixels


class Renderer:
    """Draws an env; one per env, created by ``LocalizationEnv.render()``.

    With the world's ``view_m`` set the frame follows the robot (see the module's doc): each
    :meth:`draw` moves the window onto the robot's true position (:meth:`look_at`), and
    :meth:`canvas` and :meth:`to_pixel` map through the window of the last frame drawn (the
    world's centre before the first).

    Args:
        config: the world (fixes the frame size and the static background).
        render_mode: ``"rgb_array"`` (frames returned) or ``"human"`` (a pygame window).
        fps: frame rate the ``"human"`` window is held to.

    Raises:
        ValueError: for another ``render_mode`` or a non-positive ``fps``.
    """

    def __init__(self, config: WorldConfig, render_mode: str, fps: int) -> None:
        if render_mode not in ("rgb_array", "human"):
            raise ValueError(f"render_mode must be 'rgb_array' or 'human', got {render_mode!r}")
        if fps <= 0:
            raise ValueError(f"fps must be > 0, got {fps!r}")
        self.config = config
        self.render_mode = render_mode
        self.fps = fps
        self.scale, bounds, self.width, self.view_height, left, top = _layout(config)
        #: the sensors' panels under the top view: (sensor name, height px), in config order
        self.panels = [(name, h) for name, h in zip(config.sensors, _panel_heights(config, self.width)) if h > 0]
        self.height = self.view_height + sum(h for _, h in self.panels)
        xmin, ymin, xmax, ymax = self.bounds_m = bounds
        self.is_field = config.floor == "field"
        self.floor = FIELD_FLOOR if self.is_field else ROOM_FLOOR
        self.surface = pygame.Surface((self.width, self.height), 0, 32)
        self.view_m = config.view_m
        self._view_px = (left, top)  # where the window's top left corner lies in the frame
        self._background_size = (self.width, self.view_height)
        origin = (left, top)  # the frame's pixel position of (xmin, ymax); in follow mode the background's
        if self.view_m is not None:
            self._background_size = background_size_px(bounds, self.scale)
            origin = (float(BACKGROUND_PAD_PX), float(BACKGROUND_PAD_PX))
        self._background_args = (origin, (xmin, ymax), self.floor, config.robot.radius_m)
        self._canvas_args = self._background_args
        self._offset_px = (0, 0)  # the background's pixel shown at the frame's (0, 0)
        self.window_m: Bounds = bounds  # the region the window shows: the whole world without view_m
        if self.view_m is not None:
            self.look_at((0.5 * (xmin + xmax), 0.5 * (ymin + ymax)))
        self._font = _font(_FONT_PX)
        self._background: pygame.Surface | None = None  # drawn on the first frame, from the env's walls
        self._window: pygame.Surface | None = None
        self._clock: pygame.time.Clock | None = None

    @property
    def frame_shape(self) -> tuple[int, int, int]:
        """``(H, W, 3)`` of the frames."""
        return (self.height, self.width, 3)

    def canvas(self) -> Canvas:
        """A :class:`Canvas` on this renderer's frame (also the world -> pixel mapping)."""
        return Canvas(self.surface, self.scale, *self._canvas_args)

    def to_pixel(self, xy: ArrayLike) -> NDArray[np.int64]:
        """Pixel ``(column, row)`` of world points (see :meth:`Canvas.to_pixel`)."""
        return self.canvas().to_pixel(xy)

    def look_at(self, xy: ArrayLike) -> None:
        """Follow mode: centre the window on the world point ``xy``, kept inside the world's bounds
        (centred on them along an axis where they are narrower than the window). Without
        ``view_m`` nothing changes: the frame shows the whole world."""
        if self.view_m is None:
            return
        x, y = (float(v) for v in np.asarray(xy, dtype=np.float64).reshape(2))
        x0, y0 = follow_window((x, y), self.view_m, self.bounds_m)
        x1, y1 = x0 + self.view_m[0], y0 + self.view_m[1]
        self.window_m = (x0, y0, x1, y1)
        (pad_x, pad_y), (xmin, ymax), floor, radius = self._background_args
        left, top = self._view_px
        # a whole-pixel shift: the frame is the background's pixels under the window, unresampled
        dx = round(pad_x + (x0 - xmin) * self.scale - left)
        dy = round(pad_y + (ymax - y1) * self.scale - top)
        self._offset_px = (dx, dy)
        self._canvas_args = ((pad_x - dx, pad_y - dy), (xmin, ymax), floor, radius)

    # ------------------------------------------------------------------ frames
    def draw(self, env: LocalizationEnv, overlays: Iterable[Callable[[Canvas], Any]] = ()) -> NDArray[np.uint8] | None:
        """Draw the env's current state and the overlays.

        Returns:
            ``(H, W, 3)`` uint8 frame in ``"rgb_array"`` mode, ``None`` in ``"human"`` mode.
        """
        state = env.world.snapshot()
        if self._background is None:
            self._background = self._draw_background(state)
        if self.view_m is None:
            self.surface.blit(self._background, (0, 0))
        else:
            self.look_at(state.robot_pose[:2])
            dx, dy = self._offset_px
            shown = pygame.Rect(dx, dy, self.width, self.view_height).clip(self._background.get_rect())
            self.surface.fill(BACKGROUND, pygame.Rect(0, 0, self.width, self.view_height))
            self.surface.blit(self._background, (shown.x - dx, shown.y - dy), shown)
        canvas = self.canvas()
        pose = state.robot_pose
        readings, info = env.last_observation, env.last_info
        sensors = [s for s in env.sensors.values() if s.key in readings]
        for sensor in sensors:
            if sensor.draw_layer == "under":
                sensor.draw(canvas, state, readings[sensor.key], info)
        for crowd in env.world.crowds.values():
            crowd.draw(canvas, state)
        visible = np.flatnonzero(info.get("visible_landmarks", ()))
        self._draw_landmarks(canvas, state.landmark_xy, state.landmark_radius_m, visible)
        canvas.circle(pose[0], pose[1], state.radii_m[0], ROBOT_FILL, 0)
        canvas.pose(pose[0], pose[1], pose[2], ROBOT_OUTLINE, state.radii_m[0], 2)
        for sensor in sensors:
            if sensor.draw_layer != "under":
                sensor.draw(canvas, state, readings[sensor.key], info)

        for draw in overlays:
            draw(canvas)
        self._draw_caption(env, canvas.captions)
        self._draw_panels(env, state)

        if self.render_mode == "human":
            self._show()
            return None
        # a bytearray keeps the frame writable (users annotate frames) and owned by the caller
        frame = np.frombuffer(bytearray(pygame.image.tobytes(self.surface, "RGB")), dtype=np.uint8)
        return frame.reshape(self.height, self.width, 3)

    def close(self) -> None:
        """Close the ``"human"`` window (pygame has one display per process: other windows close too)."""
        if self._window is not None:
            pygame.display.quit()
            self._window = None
            self._clock = None

    # ------------------------------------------------------------------ internals
    def _draw_background(self, state: WorldState) -> pygame.Surface:
        """Floor, field or room outline, walls and furniture (raised parts, a table's top, thin)
        and landmark labels."""
        bg = pygame.Surface(self._background_size, 0, 32)
        bg.fill(BACKGROUND)
        canvas = Canvas(bg, self.scale, *self._background_args)
        cfg = self.config
        xmin, ymin, xmax, ymax = cfg.arena_m
        corner = canvas.to_pixel([[xmin, ymax], [xmax, ymin]])
        pygame.draw.rect(bg, self.floor, pygame.Rect(*corner[0], *(corner[1] - corner[0])))
        fx0, fy0, fx1, fy1 = cfg.field_m
        outline = [(fx0, fy0), (fx1, fy0), (fx1, fy1), (fx0, fy1)]
        pygame.draw.lines(bg, FIELD_LINE if self.is_field else ROOM_OUTLINE, True, [canvas._pt(p) for p in outline], 2)
        for feature in cfg.features.values():
            feature.draw(canvas, cfg)
        for a, b, bottom in zip(state.seg_a, state.seg_b, state.seg_bottom_m):
            canvas.line(a, b, WALL, 3 if bottom <= 0.0 else 1)
        label_font = _font(_LABEL_FONT_PX)
        for lm in cfg.landmarks:
            label = label_font.render(lm.name, True, FIELD_LINE if self.is_field else WALL)
            c, r = canvas._pt((lm.x_m, lm.y_m))
            # labels sit toward the frame's (in follow mode: the world's) centre so that edge
            # landmarks keep theirs on screen
            dx = 8 if c < bg.get_width() / 2 else -8 - label.get_width()
            dy = 6 if r < bg.get_height() / 2 else -6 - label.get_height()
            bg.blit(label, (c + dx, r + dy))
        return bg

    def _draw_panels(self, env: LocalizationEnv, state: WorldState) -> None:
        """Each sensor's panel under the top view (a camera's images with what it detected)."""
        y = self.view_height
        for name, height in self.panels:
            image = env.sensors[name].panel(state, self.width, height)
            pixels = np.ascontiguousarray(np.swapaxes(np.asarray(image, dtype=np.uint8), 0, 1))
            self.surface.blit(pygame.surfarray.make_surface(pixels), (0, y))
            y += height

    def _draw_landmarks(
        self, canvas: Canvas, xy: NDArray[np.float64], radius_m: NDArray[np.float64], visible: NDArray[np.int64]
    ) -> None:
        seen = np.zeros(xy.shape[0], dtype=bool)
        seen[visible] = True
        for j in range(xy.shape[0]):
            color = landmark_color(j) if seen[j] else HIDDEN_LANDMARK
            radius_px = max(_MIN_LANDMARK_PX, round(radius_m[j] * self.scale))
            center = canvas._pt(xy[j])
            pygame.draw.circle(self.surface, color, center, radius_px)
            pygame.draw.circle(self.surface, WALL, center, radius_px, 1)

    def caption_lines(self, parts: Sequence[tuple[str, Color]]) -> list[list[tuple[int, str, Color]]]:
        """Where the caption's ``parts`` go: per line, ``(x px, text, colour)`` of each part. A part
        that would run past the frame's right edge starts a new line (a narrow world's frame, many
        overlays), so that every part is shown whole unless it alone is wider than the frame."""
        lines: list[list[tuple[int, str, Color]]] = [[]]
        x = _CAPTION_LEFT_PX
        for text, color in parts:
            shown = ("   " if lines[-1] else "") + text
            width = self._font.size(shown)[0]
            if lines[-1] and x + width > self.width:
                lines.append([])
                x, shown = _CAPTION_LEFT_PX, text
                width = self._font.size(shown)[0]
            lines[-1].append((x, shown, color))
            x += width
        return lines

    def _draw_caption(self, env: LocalizationEnv, extra: Sequence[tuple[str, Color]]) -> None:
        """The caption: the world, time and crowd, then the overlays' texts; the lines after the first
        (:meth:`caption_lines`) lie over the top of the view."""
        world = env.world
        parts = [(f"{self.config.name}  t={world.time_s:.2f} s  crowd={self.config.crowd_count}", CAPTION_TEXT), *extra]
        for row, line in enumerate(self.caption_lines(parts)):
            top = row * CAPTION_PX
            self.surface.fill(CAPTION_BACKGROUND, pygame.Rect(0, top, self.width, CAPTION_PX))
            for x, text, color in line:
                label = self._font.render(text, True, color)
                self.surface.blit(label, (x, top + (CAPTION_PX - label.get_height()) // 2))

    def _show(self) -> None:
        if self._window is None:
            pygame.display.init()
            pygame.display.set_caption(f"crowdloc: {self.config.name}")
            self._window = pygame.display.set_mode((self.width, self.height))
            self._clock = pygame.time.Clock()
        assert self._clock is not None
        pygame.event.pump()
        self._window.blit(self.surface, (0, 0))
        pygame.display.flip()
        self._clock.tick(self.fps)
