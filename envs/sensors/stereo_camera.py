"""A trinocular stereo camera that finds typed vertical edges (the far-landmark paper, paper D).

Three level, forward-looking cameras in a row, ``baseline_m`` (the paper's 19 cm) from one to
the next, the middle one ``forward_m`` ahead of the robot's centre at ``height_m``. Each frame
the sensor reports the vertical edges seen by all three cameras, each as a detection slot
``(valid, type, inverse range 1/m, bearing rad)``, flattened (``obs["stereo"].reshape(-1, 4)``):

1. **edges**: at 5 detection rows in the upper part of the image, the paper's tall filter
   (101 x 7 at 640 x 480, scaled to the resolution) on each colour channel; an edge's *type*
   is its channel, row and polarity (rising or falling), 30 types
   (:func:`envs.stereo.vision.edge_type`);
2. **matching**: left and right edges of one type, each pair confirmed by an edge of that type in
   the middle camera half-way between them (:func:`envs.stereo.vision.match_trinocular`);
3. **range and bearing** from the outer pair's disparity by the paper's eqs. (2)-(5),
   converted to the robot frame (:func:`envs.stereo.vision.rig_range_bearing`): the
   range error grows as ``r^2 / (f b)``.

Two modes produce step 1:

- ``mode: image``: each camera renders an RGB image of the 2.5-D world (a column ray caster,
  :mod:`envs.stereo.render`: façades, poles, trees, people in their clothes, cars; a person a few
  metres away covers the upper rows, a building behind rises above them), with an exposure
  gain that drifts (auto exposure) and pixel noise; the edges are found on the images, as on a
  real robot's;
- ``mode: fast`` (the default): the same edges computed from the geometry
  (:mod:`envs.stereo.geometric`: façade breaks, corners and silhouettes with the filter's
  response at each row), projected into each camera with ``edge_noise_px`` of pixel noise,
  then matched and triangulated exactly as in the image mode. Training and sweeps use it; a
  test shows both modes find the same edges on a clean scene.

**Free-running webcams** (the defaults, the paper's cameras; ``synchronised: true``,
``exposure_range: [1, 1]``, ``white_balance_k: [0, 0]`` and ``fast_edges: lines`` give synchronised
cameras of equal gains). The paper's three USB webcams have no hardware sync and their own
auto exposure and white balance. With ``synchronised: false`` each camera takes its frame
``frame_lags_s`` before the step's end (drawn per episode uniformly within one ``frame_period_s``,
the webcams' 30 fps), from the robot's pose then (:meth:`StereoCamera.camera_poses`, the swept
LIDAR's interpolation within the step); the bodies stay at their end-of-step places, as for the
LIDAR. So disparity is measured between images taken from different poses while the robot moves
or turns (a turn at 1 rad/s with a frame period between the outer pair shifts the disparity by
about 18 px). ``exposure_range`` and ``white_balance_k`` give each camera its own gain per channel
for the episode (exposure times white balance, :func:`envs.sensors.light_colour.white_balance_gains`),
applied to the rendered images and to the fast mode's edge responses alike (each camera thresholds
the responses at its own gains); they are constant over an episode, as an auto exposure holds its
setting while the scene's mean brightness stays within its stable window. Everything is drawn from
children of the sensor stream at the first frame after a reset, and only when an option is on.
The fast mode's ``fast_edges: rows`` goes with them: each camera's filter response along each
detection row is rebuilt from the lines' colour steps (:func:`envs.stereo.geometric.row_response`)
and searched by the image mode's detector, so steps closer than the filter's width add up or cancel
as in the images (``lines``: each line is an edge of its own, weakened by its neighbours).

The images are in the observation only with ``images: true`` (keys ``<key>_left``,
``<key>_middle``, ``<key>_right``, uint8 ``(H, W, 3)``); the fast mode then renders them
too. Detections beyond ``slots`` are dropped, the weakest first; the kept ones fill the slots
from left to right in the image. ``info["<key>_detections"]`` counts them,
``info["<key>_dropped"]`` the dropped.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from core.geometry import poses_along_step
from core.schema import ConfigError, check, check_ranges, is_real
from envs.sensors.base import SensorBase, SensorConfig, register_sensor
from envs.sensors.light_colour import CCT_RANGE_K, white_balance_gains
from envs.state import WorldState
from envs.stereo.edges import find_edges
from envs.stereo.geometric import camera_edges, lines, row_response
from envs.stereo.render import ColumnRenderer, Moving
from envs.stereo.scene import Rig, static_scene
from envs.stereo.vision import (
    CHANNEL_COLOURS,
    EDGE_TYPES,
    LEVELS,
    EdgeDetector,
    EdgeList,
    TrinocularRig,
    check_rows,
    disparity_window,
    draw_detections,
    edge_types,
    edge_types_parts,
    filter_size,
    match_checked,
)

if TYPE_CHECKING:
    from envs.config import WorldConfig

#: one slot: (valid, type, inverse range 1/m, bearing rad)
SLOT_FIELDS = ("valid", "type", "inverse_range_m", "bearing_rad")
CAMERAS = ("left", "middle", "right")
_NOISE_POOL = 1 << 18  # noise offsets drawn per frame (the pool holds this plus one frame)

#: overrides that make the cameras ideal (no pixel noise, no exposure changes, no edge noise; synchronised, of
#: equal gains): for tests and studies
IDEAL = {"pixel_noise_std": 0.0, "gain_std": 0.0, "edge_noise_px": 0.0, "synchronised": True, "exposure_range": (1.0, 1.0),
         "white_balance_k": (0.0, 0.0)}  # fmt: skip


@dataclass(frozen=True)
class StereoCameraConfig(SensorConfig):
    """Three forward cameras in a row and their edge detection (module docstring).

    Defaults: the paper's rig (19 cm between neighbours) of 640 x 480 webcams with a 60 deg
    horizontal field of view (f = 554 px; ours: the paper names the BUFFALO BSW200MBK, not its
    lens), about 1 m up (ours: the robot's photo). ``detection_rows_px``: the 5 rows, top to
    bottom, in the image's upper part (None: evenly from 1/8 to 11/24 of the height, 60-220 at
    480 px); ``threshold``: the least filter response of an edge, in 0-255 units of the
    channel step it sees (ours: the paper thresholds without giving the value);
    ``match_tolerance_px``: how near the middle camera's edge must be to the pair's midpoint;
    ``min_range_m``, ``max_range_m``: the depths matching considers (nearer than where the
    three views overlap nothing can be matched: ``2 baseline f / width``).
    Image mode: ``pixel_noise_std`` (0-255 units), the exposure gain's auto-exposure drift
    (``gain_std`` per step, pulled back to 1 at ``gain_rho`` per step, within ``gain_range``);
    fast mode: ``edge_noise_px``, the sd of an edge's column in each camera.
    """

    key: str = "stereo"
    mode: Literal["fast", "image"] = "fast"
    images: bool = False
    width_px: int = 640
    height_px: int = 480
    focal_px: float = 554.26
    principal_point_px: tuple[float, float] | None = None  # (cx, cy); None: the image centre
    baseline_m: float = 0.19
    height_m: float = 1.0
    forward_m: float = 0.2
    detection_rows_px: tuple[int, ...] | None = None
    threshold: float = 18.0
    match_tolerance_px: float = 1.5
    min_range_m: float = 1.0
    max_range_m: float = 100.0
    slots: int = 96
    edge_noise_px: float = 0.4
    pixel_noise_std: float = 2.0
    gain_std: float = 0.01
    gain_rho: float = 0.98
    gain_range: tuple[float, float] = (0.8, 1.2)
    render_range_m: float = 200.0  # nothing farther is drawn or seen
    show_images: bool = True  # rendered frames show the three images with their edges under the top view
    # ---- free-running webcams (the paper's cameras are the defaults; the values in brackets give synchronised
    # cameras of equal gains). The paper's three BUFFALO BSW200MBK USB webcams have no hardware sync: each streams on
    # its own clock. false (the default): each camera's frame is taken frame_lags_s before the end of the step
    # (drawn per episode, uniform within one frame period, unless given), from the robot's pose then; [true]: all
    # at the step's end.
    synchronised: bool = False
    # one frame period of a camera. No BSW200MBK datasheet was found; 1/30 s is the USB Video Class's
    # 640 x 480 rate that such webcams stream by default (their UVC descriptors: default interval 1/30)
    frame_period_s: float = 1.0 / 30.0
    frame_lags_s: tuple[float, float, float] | None = None  # (left, middle, right) fixed lags (tests, studies); None: drawn
    # each camera's exposure gain, drawn per camera and episode uniformly within this range; [(1, 1)]: equal
    # exposures. The default (0.51, 1.49) is the auto-exposure's stable window of a VGA
    # webcam sensor: the OmniVision OV7670's AEC leaves the exposure alone while the mean luma lies within
    # AEB..AEW, 0x33..0x95 (51..149 about 100) as the Linux driver (drivers/media/i2c/ov7670.c) sets them, so
    # two free-running cameras on one scene settle anywhere in it (the BSW200MBK's sensor is not published)
    exposure_range: tuple[float, float] = (0.51, 1.49)
    # each camera's auto white balance: the colour temperature (K) it balances for, drawn per camera and episode
    # uniformly within this range, under daylight of light_k; [(0, 0)]: none (neutral colours). The default
    # (5003, 7504) is the CIE daylight illuminants D50-D75 (CIE 15:2004) that a camera's auto white
    # balance estimates from its own view, under light_k 6504 (D65, average daylight) (ours: the spread of the
    # BSW200MBK's white balance is not published). Gains: envs.sensors.light_colour.white_balance_gains
    white_balance_k: tuple[float, float] = (5003.0, 7504.0)
    light_k: float = 6504.0
    # how the fast mode turns the lines into each camera's edges. [lines]: each line above the threshold is
    # an edge at its column, of two of a type within the filter's width the stronger kept; rows: the filter's
    # response along each detection row rebuilt from the lines' colour steps at the pixel boundaries where the
    # image puts them, and searched for peaks by the image mode's detector (envs.stereo.geometric.row_response), so
    # that steps closer than the filter's width add up or cancel as in the images, and an edge's column is where the
    # image's detector puts it (whole pixels for a sharp step; edge_noise_px is not used): the default, which agrees
    # with the image mode within 5 % per row and type on the campus (benchmarks/stereo_webcams.py measures it)
    fast_edges: Literal["lines", "rows"] = "rows"

    def __post_init__(self) -> None:
        where = "stereo_camera"
        check(self.mode in ("fast", "image"), f"{where}.mode must be 'fast' or 'image', got {self.mode!r}")
        check(32 <= self.width_px <= 4096, f"{where}.width_px must be in 32..4096, got {self.width_px}")
        check(32 <= self.height_px <= 4096, f"{where}.height_px must be in 32..4096, got {self.height_px}")
        check_ranges(self, where, positive=("focal_px", "baseline_m", "min_range_m", "max_range_m", "match_tolerance_px",
                                            "threshold", "render_range_m"))  # fmt: skip
        cx, cy = self.principal
        check(
            0 < cx < self.width_px and 0 < cy < self.height_px,
            f"{where}.principal_point_px {(cx, cy)} must lie inside the {self.width_px} x {self.height_px} image",
        )
        check(math.isfinite(self.height_m) and self.height_m > 0, f"{where}.height_m must be finite and > 0, got {self.height_m}")
        check(math.isfinite(self.forward_m), f"{where}.forward_m must be finite, got {self.forward_m}")
        check(
            self.min_range_m < self.max_range_m,
            f"{where}: min_range_m {self.min_range_m} must be below max_range_m {self.max_range_m}",
        )
        overlap = self.overlap_depth_m
        check(
            overlap < self.min_range_m,
            f"{where}: the cameras do not overlap where matching starts: with baseline_m {self.baseline_m} (outer pair "
            f"{2 * self.baseline_m:g} m), focal_px {self.focal_px} and width_px {self.width_px} the three views share "
            f"nothing nearer than {overlap:.3g} m, beyond min_range_m {self.min_range_m}",
        )
        rows, _ = filter_size(self.width_px, self.height_px)
        try:
            check_rows(self.rows, self.height_px, rows, f"{where}.detection_rows_px")
        except ValueError as exc:
            raise ConfigError(str(exc)) from None
        check(len(self.rows) == LEVELS, f"{where}.detection_rows_px must be {LEVELS} rows, got {self.rows}")
        check(1 <= self.slots <= 1024, f"{where}.slots must be in 1..1024, got {self.slots}")
        check_ranges(self, where, non_negative=("edge_noise_px", "pixel_noise_std", "gain_std"))
        check(0 <= self.gain_rho < 1, f"{where}.gain_rho must be in [0, 1), got {self.gain_rho}")
        lo, hi = self.gain_range
        check(0 < lo <= 1 <= hi < math.inf, f"{where}.gain_range must hold 1 and be positive, got {self.gain_range}")
        self._check_webcams(where)

    @property
    def frame_gap_s(self) -> float:
        """The longest time between two of the rig's frames: 0 for synchronised cameras, the spread of
        ``frame_lags_s`` when they are given, else one frame period (the lags are drawn within it). A frame
        taken while the robot turns at ``w`` rad/s has its bearings off by up to ``w`` times this between
        the cameras (the metadata carries it, so a localizer can tell a turn from a wrong pose)."""
        if self.synchronised:
            return 0.0
        if self.frame_lags_s is not None:
            return float(max(self.frame_lags_s) - min(self.frame_lags_s))
        return float(self.frame_period_s)

    def _check_webcams(self, where: str) -> None:
        """The free-running webcams' fields."""
        period = self.frame_period_s
        check(math.isfinite(period) and period > 0, f"{where}.frame_period_s must be finite and > 0 s, got {period}")
        if self.frame_lags_s is not None:
            check(
                not self.synchronised,
                f"{where}.frame_lags_s {self.frame_lags_s} is given but synchronised is true (every frame at the step's end)",
            )
            lags = tuple(self.frame_lags_s)
            check(
                len(lags) == 3 and all(is_real(v) and 0 <= v <= period for v in lags),
                f"{where}.frame_lags_s must be three lags (left, middle, right) in [0, frame_period_s = {period:g}] s, got "
                f"{self.frame_lags_s}",
            )
        lo, hi = self.exposure_range
        check(
            0 < lo <= hi < math.inf,
            f"{where}.exposure_range must be (low, high) with 0 < low <= high, finite, got {self.exposure_range}",
        )
        check(self.fast_edges in ("lines", "rows"), f"{where}.fast_edges must be 'lines' or 'rows', got {self.fast_edges!r}")
        cct_lo, cct_hi = CCT_RANGE_K
        wb_lo, wb_hi = self.white_balance_k
        check(
            (wb_lo, wb_hi) == (0, 0) or cct_lo <= wb_lo <= wb_hi <= cct_hi,
            f"{where}.white_balance_k must be (0, 0) (none) or (low, high) within {cct_lo:g}..{cct_hi:g} K, got "
            f"{self.white_balance_k}",
        )
        check(cct_lo <= self.light_k <= cct_hi, f"{where}.light_k must be within {cct_lo:g}..{cct_hi:g} K, got {self.light_k}")

    def check_world(self, world: WorldConfig, name: str) -> None:
        """Refuse unsynchronised cameras whose frames may be older than one step: the sensor knows the
        robot's pose at the start and the end of the step only (as the swept LIDAR)."""
        check(
            self.synchronised or self.frame_period_s <= world.dt_s,
            f"sensor {name!r}: stereo_camera.frame_period_s = {self.frame_period_s} s is longer than the world's step "
            f"dt_s = {world.dt_s} s; an unsynchronised camera's frame is taken from the robot's pose within the step, "
            "so a frame period must fit in one",
        )

    @property
    def camera_effects(self) -> bool:
        """Whether any free-running webcam effect is on (unsynchronised frames, unequal exposures or white balance)."""
        return not self.synchronised or tuple(self.exposure_range) != (1.0, 1.0) or tuple(self.white_balance_k) != (0, 0)

    def panel_height_px(self, frame_width_px: int) -> int:
        """With ``show_images``, the three images side by side scaled to the frame's width (an even height)."""
        if not self.show_images:
            return 0
        return 2 * max(1, round(frame_width_px * self.height_px / (3 * self.width_px) / 2))

    @property
    def principal(self) -> tuple[float, float]:
        """``(cx, cy)``: the principal point (the image centre by default)."""
        if self.principal_point_px is None:
            return (0.5 * self.width_px, 0.5 * self.height_px)
        return (float(self.principal_point_px[0]), float(self.principal_point_px[1]))

    @property
    def rows(self) -> tuple[int, ...]:
        """The detection rows, top to bottom (level 0 first)."""
        if self.detection_rows_px is not None:
            return tuple(int(r) for r in self.detection_rows_px)
        return tuple(int(round(self.height_px * (1.5 + k) / 12.0)) for k in range(LEVELS))

    @property
    def overlap_depth_m(self) -> float:
        """The depth from which all three cameras see a point: ``2 baseline f / width``."""
        return 2.0 * self.baseline_m * self.focal_px / self.width_px

    def rig(self) -> Rig:
        cx, cy = self.principal
        return Rig(self.focal_px, cx, cy, self.width_px, self.height_px, self.height_m, self.forward_m, self.baseline_m)


@register_sensor("stereo_camera", StereoCameraConfig)
class StereoCamera(SensorBase):
    """The trinocular camera (module docstring). :meth:`render` draws any pose's three images;
    :meth:`views` the last frame's with its detections marked."""

    draw_layer = "over"

    def __init__(self, name: str, config: StereoCameraConfig, world: WorldConfig, state: WorldState) -> None:
        self.name = name
        self.key = config.key
        self.config = config
        c = config
        self.rig_geometry = c.rig()
        self.scene = static_scene(world)
        fr, fc = filter_size(c.width_px, c.height_px)
        self.detector = EdgeDetector(c.rows, fr, fc, c.threshold)
        cx, cy = c.principal
        self.matcher = TrinocularRig(
            c.focal_px, cx, c.baseline_m, c.min_range_m, c.max_range_m, c.match_tolerance_px, c.forward_m, 0.0
        )
        self._window = disparity_window(c.focal_px, c.baseline_m, c.min_range_m, c.max_range_m)
        self.renderer = ColumnRenderer(self.scene, c.focal_px, cx, cy, c.width_px, c.height_px, c.height_m, c.render_range_m)
        self._rows = np.asarray(c.rows, dtype=np.int64)
        self._half = fr // 2
        self._margin_px = fc // 2 + 1.0  # an edge nearer the border than the filter's half width is not found
        sc = self.scene
        n_static = sc.seg_a.shape[0]
        self._n_static = n_static
        self._static_cull = np.ascontiguousarray(sc.seg_floor & (sc.seg_z1 >= c.height_m))
        obj_z0 = np.array([sc.seg_z0[f] for f in sc.obj_first], dtype=np.float64)
        obj_z1 = np.array([sc.seg_z1[f] for f in sc.obj_first], dtype=np.float64)
        self._obj = (sc.obj_first, sc.obj_count, obj_z0, obj_z1)
        frame = c.height_px * c.width_px * 3
        self._noise = np.zeros(0, dtype=np.float32)
        self._frame = frame
        self._gain = 1.0
        self._fresh = True
        self._dt_s = float(world.dt_s)
        # the free-running webcams, drawn per episode when on: each camera's lag behind the
        # step's end (s) and its gain per channel (exposure x white balance); None: synchronised cameras of equal gains
        self.frame_lags_s: NDArray[np.float64] | None = None
        self.camera_gains: NDArray[np.float64] | None = None
        self.last_images: tuple[NDArray[np.uint8], ...] | None = None
        self.last_edges: tuple[EdgeList, ...] = ()
        self.last_slots = np.zeros((c.slots, 4), dtype=np.float32)
        self._state_of_images: WorldState | None = None

    # ------------------------------------------------------------------ interface
    def space(self) -> spaces.Box | spaces.Dict:
        c = self.config
        low = np.tile(np.array([0.0, 0.0, 0.0, -math.pi], dtype=np.float32), c.slots)
        high = np.tile(np.array([1.0, EDGE_TYPES - 1, 1.0 / c.min_range_m, math.pi], dtype=np.float32), c.slots)
        slots = spaces.Box(low, high, dtype=np.float32)
        if not c.images:
            return slots
        image = spaces.Box(0, 255, shape=(c.height_px, c.width_px, 3), dtype=np.uint8)
        return spaces.Dict({self.key: slots, **{f"{self.key}_{cam}": image for cam in CAMERAS}})

    def reset(self) -> None:
        self._fresh = True
        self._gain = 1.0
        self.frame_lags_s = None
        self.camera_gains = None
        self.last_images = None
        self._state_of_images = None

    def metadata(self) -> dict[str, Any]:
        c, r = self.config, self.rig_geometry
        return {
            "width_px": c.width_px,
            "height_px": c.height_px,
            "focal_px": r.focal_px,
            "cx_px": r.cx_px,
            "cy_px": r.cy_px,
            "baseline_m": c.baseline_m,
            "forward_m": c.forward_m,
            "height_m": c.height_m,
            "rows_px": list(c.rows),
            "threshold": c.threshold,
            "slots": c.slots,
            "min_range_m": c.min_range_m,
            "max_range_m": c.max_range_m,
            "edge_types": EDGE_TYPES,
            "slot_fields": list(SLOT_FIELDS),
            "mode": c.mode,
            "frame_gap_s": c.frame_gap_s,
        }

    # ------------------------------------------------------------------ frames
    def _moving(self, state: WorldState) -> Moving:
        app = state.figures.appearance()
        return (app.side_a, app.side_b, app.side_z0, app.side_z1, app.side_rgb,
                app.disc_xy, app.disc_r, app.disc_z0, app.disc_z1, app.disc_rgb)  # fmt: skip

    def render(
        self,
        pose: NDArray[np.float64],
        state: WorldState,
        gain: float | NDArray[np.float64] = 1.0,
        noise_offsets: tuple[int, ...] | None = None,
    ) -> tuple[NDArray[np.uint8], NDArray[np.uint8], NDArray[np.uint8]]:
        """The three cameras' images (left, middle, right) at robot ``pose`` among ``state``'s bodies.

        Args:
            pose: ``(3,)`` the robot's pose, or ``(3, 3)`` one per camera (each camera on the rig
                where the robot was when it took its frame).
            gain: the exposure gain: one number, or ``(3, 3)`` per camera and channel;
                ``noise_offsets``: where each image reads the noise pool (None: no noise; the pool
                is filled at the first frame after a reset).
        """
        p = np.asarray(pose, dtype=np.float64)
        if p.ndim == 2:
            cams, forwards = self.rig_geometry.cameras_at(p)
        else:
            cams, forward = self.rig_geometry.cameras(p)
            forwards = np.stack([forward] * 3)
        gains = np.broadcast_to(np.asarray(gain, dtype=np.float64), (3, 3)) if np.ndim(gain) else None
        moving = self._moving(state)
        out = []
        for j in range(3):
            noise = None
            if noise_offsets is not None and self._noise.size:
                start = int(noise_offsets[j])
                noise = self._noise[start : start + self._frame]
            out.append(self.renderer.render(cams[j], forwards[j], moving, gain if gains is None else gains[j], noise))
        return out[0], out[1], out[2]

    def camera_poses(self, state: WorldState) -> NDArray[np.float64]:
        """``(3,)`` the robot's pose at the step's end, or with unsynchronised cameras ``(3, 3)``
        the robot's pose when each camera took its frame: ``frame_lags_s`` before the step's end,
        along the step's motion (:func:`core.geometry.poses_along_step`, the model the swept
        LIDAR uses). The bodies stay where they are at the step's end (a walker at 1.5 m/s moves
        5 cm in a 30 fps frame period)."""
        if self.frame_lags_s is None:
            return state.robot_pose
        return poses_along_step(state.robot_start, state.robot_pose, self.frame_lags_s / self._dt_s)

    def _exposures(self) -> float | NDArray[np.float64]:
        """The exposure gain of each camera and channel now: the common auto-exposure drift, times each
        camera's own gains when they differ (``(3, 3)``), else one number."""
        if self.camera_gains is None:
            return self._gain
        return self._gain * self.camera_gains

    def _draw_webcams(self, rng: np.random.Generator) -> None:
        """Each camera's frame lag and gains for this episode, from children of ``rng`` (which leaves its
        own draws as they were: nothing is drawn while the cameras are synchronised and of equal gains)."""
        c = self.config
        if not c.camera_effects:
            return
        timing, exposure = rng.spawn(2)
        if not c.synchronised:
            given = c.frame_lags_s
            self.frame_lags_s = (
                np.asarray(given, dtype=np.float64) if given is not None else timing.uniform(0.0, c.frame_period_s, 3)
            )
        lo, hi = c.exposure_range
        gains = exposure.uniform(lo, hi, 3)[:, None] * np.ones((3, 3))
        if tuple(c.white_balance_k) != (0, 0):
            balance = exposure.uniform(*c.white_balance_k, 3)
            gains = gains * np.stack([white_balance_gains(c.light_k, float(k)) for k in balance])
        self.camera_gains = None if np.all(gains == 1.0) else gains

    def _step_exposure(self, rng: np.random.Generator) -> None:
        c = self.config
        if self._fresh:
            self._draw_webcams(rng)
            if c.pixel_noise_std > 0 and (c.mode == "image" or c.images):
                self._noise = (rng.standard_normal(_NOISE_POOL + self._frame) * c.pixel_noise_std).astype(np.float32)
            self._gain = 1.0
            self._fresh = False
        if c.gain_std > 0:
            lo, hi = c.gain_range
            self._gain = float(np.clip(1.0 + c.gain_rho * (self._gain - 1.0) + c.gain_std * rng.standard_normal(), lo, hi))

    def _render_frame(self, state: WorldState, rng: np.random.Generator) -> tuple[NDArray[np.uint8], ...]:
        offsets = tuple(int(v) for v in rng.integers(_NOISE_POOL, size=3)) if self._noise.size else None
        images = self.render(self.camera_poses(state), state, self._exposures(), offsets)
        self.last_images = images
        self._state_of_images = state
        return images

    def _image_edges(self, images: tuple[NDArray[np.uint8], ...]) -> tuple[EdgeList, EdgeList, EdgeList]:
        left, middle, right = (self.detector.detect(image) for image in images)
        return left, middle, right

    def _fast_edges(self, state: WorldState, rng: np.random.Generator) -> tuple[EdgeList, EdgeList, EdgeList]:
        c, r = self.config, self.rig_geometry
        poses = self.camera_poses(state)
        if poses.ndim == 2:  # unsynchronised: the lines as the middle camera saw them when it took its frame
            cams, forwards = r.cameras_at(poses)
            forward = forwards[1]
        else:
            cams, forward = r.cameras(poses)
            forwards = np.stack([forward] * 3)
        exposures = self._exposures()
        brightest = 1.0 if self.camera_gains is None else float(self.camera_gains.max())  # no line weaker can count
        # lines narrower in the image than half the filter respond weaker (the lines model); the rows model's
        # filter finds that itself (a narrow pole's two silhouettes cancel), so it takes every line at full strength
        weaken = c.fast_edges == "lines"
        app = state.figures.appearance()
        sc = self.scene
        seg_a = np.concatenate((sc.seg_a, app.side_a))
        seg_b = np.concatenate((sc.seg_b, app.side_b))
        seg_z0 = np.concatenate((sc.seg_z0, app.side_z0))
        seg_z1 = np.concatenate((sc.seg_z1, app.side_z1))
        cull = np.concatenate((self._static_cull, np.zeros(app.side_a.shape[0], dtype=np.bool_)))
        obj_first, obj_count, obj_z0, obj_z1 = self._obj
        boxes = app.side_a.shape[0] // 4
        if boxes:
            obj_first = np.concatenate((obj_first, self._n_static + 4 * np.arange(boxes)))
            obj_count = np.concatenate((obj_count, np.full(boxes, 4, dtype=np.int64)))
            obj_z0 = np.concatenate((obj_z0, app.side_z0[::4]))
            obj_z1 = np.concatenate((obj_z1, app.side_z1[::4]))
        x, z, level, response = lines(
            cams[1], forward, r.focal_px, r.cx_px, r.cy_px, r.width_px, r.height_m, c.render_range_m,
            self._rows, self._half, self._margin_px, c.threshold / c.gain_range[1] / brightest,
            float(self.detector.filter_cols // 2), weaken,
            seg_a, seg_b, seg_z0, seg_z1, cull, self._n_static, sc.seg_profile, sc.seg_length, sc.seg_rgb, app.side_rgb,
            obj_first, obj_count, obj_z0, obj_z1,
            sc.seg_first_brk, sc.brk_xy, sc.brk_first_run, sc.brun_z0, sc.brun_z1, sc.brun_left, sc.brun_right,
            app.disc_xy, app.disc_r, app.disc_z0, app.disc_z1, app.disc_rgb,
            sc.prof_first, sc.int_s1, sc.int_first_run, sc.run_z0, sc.run_z1, sc.run_rgb, self.renderer.background,
        )  # fmt: skip
        within = self.detector.filter_cols // 2 + 1.5  # two steps of one sign this close make one peak of the filter
        # the left camera sits baseline_m left of the middle one: a point X right of the middle camera is X + b right of it
        laterals = (c.baseline_m, 0.0, -c.baseline_m)
        if c.fast_edges == "lines" and self.camera_gains is None and self.frame_lags_s is None:  # one exposure, one time
            strength = np.abs(response) * self._gain  # (N, 3)
            line, channel = np.nonzero(strength >= c.threshold)
            types = edge_types(channel, level[line], response[line, channel] < 0)
            power = strength[line, channel].astype(np.float32)
            xs, zs = x[line], z[line]
            noise = rng.standard_normal((3, line.size)) * c.edge_noise_px if c.edge_noise_px > 0 else np.zeros((3, line.size))
            lists = [
                EdgeList(
                    *camera_edges(
                        xs, zs, types, power, lateral, r.focal_px, r.cx_px, r.width_px, self._margin_px, noise[j], within
                    )
                )
                for j, lateral in enumerate(laterals)
            ]
            return lists[0], lists[1], lists[2]
        # free-running webcams: each camera thresholds the lines at its own gains and sees them from its own pose
        gains = np.broadcast_to(np.asarray(exposures, dtype=np.float64), (3, 3))
        world = cams[1] + x[:, None] * np.array([forward[1], -forward[0]]) + z[:, None] * forward  # (N, 2) the lines' points
        lists = []
        half_cols = self.detector.filter_cols // 2
        for j in range(3):
            if self.frame_lags_s is None:
                xs, zs, lateral = x, z, laterals[j]
            else:  # the lines' points in camera j's frame when it took its frame
                offset = world - cams[j]
                fwd_j = forwards[j]
                xs, zs, lateral = offset @ np.array([fwd_j[1], -fwd_j[0]]), offset @ fwd_j, 0.0
            if c.fast_edges == "rows":  # the filter's response along each row from the steps, searched as in the image
                u = r.cx_px + r.focal_px * (xs + lateral) / zs
                rows = row_response(u, level, response, np.ascontiguousarray(gains[j]), r.width_px, LEVELS, half_cols)
                lists.append(find_edges(rows, float(c.threshold), half_cols))
                continue
            strength = np.abs(response) * gains[j]  # (N, 3)
            line, channel = np.nonzero(strength >= c.threshold)
            types = edge_types(channel, level[line], response[line, channel] < 0)
            power = strength[line, channel].astype(np.float32)
            noise = rng.standard_normal(line.size) * c.edge_noise_px if c.edge_noise_px > 0 else np.zeros(line.size)
            edges = camera_edges(xs[line], zs[line], types, power, lateral, r.focal_px, r.cx_px, r.width_px, self._margin_px,
                                 noise, within)  # fmt: skip
            lists.append(EdgeList(*edges))
        return lists[0], lists[1], lists[2]

    def observe(
        self, state: WorldState, rng: np.random.Generator
    ) -> tuple[NDArray[np.float32] | dict[str, NDArray[Any]], dict[str, Any]]:
        c = self.config
        self._step_exposure(rng)
        images = self._render_frame(state, rng) if (c.mode == "image" or c.images) else None
        if c.mode == "image":
            assert images is not None
            edges = self._image_edges(images)
        else:
            edges = self._fast_edges(state, rng)
        self.last_edges = edges
        matches = match_checked(*edges, *self._window, c.match_tolerance_px)
        slots, dropped = self._slots(matches)
        self.last_slots = slots
        slots = slots.reshape(-1)  # flat, as stable-baselines3's policies take a vector
        info = {f"{self.key}_detections": int(min(matches.type.size, c.slots)), f"{self.key}_dropped": dropped}
        if not c.images:
            return slots, info
        assert images is not None
        return {self.key: slots, **{f"{self.key}_{cam}": img for cam, img in zip(CAMERAS, images)}}, info

    def _slots(self, matches: Any) -> tuple[NDArray[np.float32], int]:
        c = self.config
        slots = np.zeros((c.slots, 4), dtype=np.float32)
        count = matches.type.size
        if count == 0:
            return slots, 0
        ranges, bearings = self.matcher.range_bearing(matches)
        keep = np.arange(count)
        if count > c.slots:  # the weakest go
            keep = np.argsort(-matches.strength, kind="stable")[: c.slots]
        keep = keep[np.argsort(-bearings[keep], kind="stable")]  # left to right in the image
        n = keep.size
        slots[:n, 0] = 1.0
        slots[:n, 1] = matches.type[keep]
        slots[:n, 2] = np.minimum(1.0 / ranges[keep], 1.0 / c.min_range_m)
        slots[:n, 3] = bearings[keep]
        return slots, count - n

    # ------------------------------------------------------------------ drawing
    def views(self, state: WorldState, width_px: int | None = None, height_px: int | None = None) -> NDArray[np.uint8]:
        """The three cameras' last images side by side (rendered now in the fast mode), each with
        its edges marked by type (:func:`envs.stereo.vision.draw_detections`: a marker in
        its channel's colour on its row, hollow for a rising edge, filled for a falling one);
        scaled to ``(height_px, width_px)`` when given (markers drawn after scaling)."""
        import cv2

        c = self.config
        images = self.last_images
        if images is None or self._state_of_images is not state:
            images = self.render(self.camera_poses(state), state, self._exposures())
        width = 3 * c.width_px if width_px is None else int(width_px)
        height = c.height_px if height_px is None else int(height_px)
        edges = self.last_edges or (None, None, None)
        bounds = np.linspace(0, width, 4).round().astype(int)
        sy = height / c.height_px
        rows = np.clip(np.round(self._rows * sy).astype(np.int64), 0, height - 1)
        marked = []
        for j, (image, found) in enumerate(zip(images, edges)):
            w = int(bounds[j + 1] - bounds[j])
            small = image
            if (w, height) != (c.width_px, c.height_px):
                small = np.asarray(cv2.resize(image, (w, height), interpolation=cv2.INTER_AREA), dtype=np.uint8)
            if found is not None:
                sx = w / c.width_px
                small = draw_detections(small, found.u * sx, found.type, rows, radius_px=2 if sx < 0.6 else 4)
            marked.append(small)
        return np.concatenate(marked, axis=1)

    def panel(self, state: WorldState, width_px: int, height_px: int) -> NDArray[np.uint8]:
        """:meth:`views` at the rendered frame's strip size."""
        return self.views(state, width_px, height_px)

    def draw(self, canvas: Any, state: WorldState, reading: NDArray[np.float32], info: Mapping[str, Any]) -> None:
        """A ray from the robot to each detection, in its channel's colour."""
        slots = np.asarray(reading).reshape(-1, 4)
        seen = slots[slots[:, 0] > 0.5]
        if not seen.shape[0]:
            return
        x, y, theta = state.robot_pose
        channel, _, _ = edge_types_parts(seen[:, 1].astype(np.int64))
        rng = 1.0 / seen[:, 2]
        ends = np.stack([x + rng * np.cos(theta + seen[:, 3]), y + rng * np.sin(theta + seen[:, 3])], axis=1)
        for (ex, ey), ch in zip(ends, channel):
            canvas.line((x, y), (ex, ey), CHANNEL_COLOURS[int(ch)], 1)
