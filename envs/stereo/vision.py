"""The stereo paper's landmarks (paper D): vertical edges seen by a trinocular camera rig.

A robot carries three forward cameras in a row, ``b = 0.19`` m from one to the next. Each
image is searched for vertical edges in its upper part; an edge seen by all three cameras
is triangulated with the outer pair and becomes a landmark at a range and bearing.

1. :func:`vertical_edge_response`: the paper's tall ``m x n`` filter (101 x 7 at 640 x 480,
   :func:`filter_size` scales it) at up to 5 detection rows, in each colour channel;
2. :func:`detect_edges`: thresholded local maxima of the response with sub-pixel position;
   each edge gets one of 30 *types* (channel x level x polarity, :func:`edge_type`);
3. :func:`match_trinocular`: left/right pairs of one type, each confirmed by the middle camera;
4. :func:`triangulate`, :func:`paper_range_bearing`: the paper's eqs. (2)-(5);
   :func:`rig_range_bearing`: the same point in the robot frame, in crowdloc's convention
   (the one place the paper's bearing convention is converted).

This module is the one import for all of it (what the stereo camera sensor and the tests
use); the code lives in two modules along the pipeline's seam:

- :mod:`envs.stereo.edges`: one camera's image: the edge types, the filter, detection,
  :class:`EdgeDetector`, :func:`draw_detections`, and the pixel convention (column ``k``
  spans ``[k, k + 1)``, its ray through ``k + 0.5``; shared with the renderer and the
  geometric fast mode of :mod:`envs.stereo`);
- :mod:`envs.stereo.matching`: the rig: trinocular matching, triangulation,
  :class:`TrinocularRig`, and the frames' convention (the paper's stereo frame vs crowdloc's
  robot frame).

Everything works on plain arrays (no env objects), so it runs on a real camera's frames
too: uint8 RGB images of shape ``(H, W, 3)``.
"""

from __future__ import annotations

from envs.stereo.edges import (
    CHANNEL_COLOURS,
    CHANNELS,
    EDGE_TYPES,
    LEVELS,
    PAPER_FILTER_COLS,
    PAPER_FILTER_ROWS,
    PAPER_HEIGHT_PX,
    PAPER_WIDTH_PX,
    POLARITIES,
    EdgeDetector,
    EdgeList,
    check_edge_types,
    check_edges,
    check_rgb_image,
    check_rows,
    concat_edges,
    detect_edges,
    draw_detections,
    edge_type,
    edge_type_parts,
    edge_types,
    edge_types_parts,
    empty_edges,
    filter_size,
    vertical_edge_response,
)
from envs.stereo.matching import (
    Matches,
    TrinocularRig,
    disparity_window,
    empty_matches,
    inverse_range_std,
    match_checked,
    match_trinocular,
    paper_range_bearing,
    range_std_m,
    rig_range_bearing,
    triangulate,
)

__all__ = [
    "CHANNELS",
    "CHANNEL_COLOURS",
    "EDGE_TYPES",
    "LEVELS",
    "PAPER_FILTER_COLS",
    "PAPER_FILTER_ROWS",
    "PAPER_HEIGHT_PX",
    "PAPER_WIDTH_PX",
    "POLARITIES",
    "EdgeDetector",
    "EdgeList",
    "Matches",
    "TrinocularRig",
    "check_edge_types",
    "check_edges",
    "check_rgb_image",
    "check_rows",
    "concat_edges",
    "detect_edges",
    "disparity_window",
    "draw_detections",
    "edge_type",
    "edge_type_parts",
    "edge_types",
    "edge_types_parts",
    "empty_edges",
    "empty_matches",
    "filter_size",
    "inverse_range_std",
    "match_checked",
    "match_trinocular",
    "paper_range_bearing",
    "range_std_m",
    "rig_range_bearing",
    "triangulate",
    "vertical_edge_response",
]
