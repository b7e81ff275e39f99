"""The colour of light in the ceiling camera's images: a light's colour temperature against the
camera's white balance, fixed or automatic (grey world), one gain per channel
(:class:`envs.sensors.ceiling_camera.CeilingCameraConfig`'s ``white_balance_k``, ``cct_k``,
``daylight_cct_k`` and ``auto_white_balance``)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from core.schema import check

#: the colour temperatures the Planckian-locus fit of :func:`cct_white_rgb` covers with every
#: linear sRGB channel of the white positive (Krystek's fit holds over 1000-15000 K; below about
#: 1700 K the locus leaves the sRGB gamut)
CCT_RANGE_K = (2000.0, 15000.0)
#: sRGB's linear RGB from CIE XYZ (IEC 61966-2-1:1999, the D65 white point)
XYZ_TO_SRGB = np.array([[3.2406, -1.5372, -0.4986], [-0.9689, 1.8758, 0.0415], [0.0557, -0.2040, 1.0570]])


def cct_white_rgb(cct_k: float) -> NDArray[np.float64]:
    """The linear sRGB of a Planckian (black-body) white of colour temperature ``cct_k``, green 1.

    Krystek's rational fit of the Planckian locus in CIE 1960 (u, v) (M. Krystek, "An algorithm to
    calculate correlated colour temperature", Color Research & Application 10(1), 1985, 38-40;
    within 1e-4 of the locus over 1000-15000 K), then CIE (x, y), XYZ at Y = 1 and sRGB's matrix
    (IEC 61966-2-1). A light's colour is taken as that of the black body at its CCT (fluorescent
    and daylight lie close to the locus: F2 and D55 within 0.003 and 0.004 in (u, v)).
    """
    t = float(cct_k)
    u = (0.860117757 + 1.54118254e-4 * t + 1.28641212e-7 * t * t) / (1 + 8.42420235e-4 * t + 7.08145163e-7 * t * t)
    v = (0.317398726 + 4.22806245e-5 * t + 4.20481691e-8 * t * t) / (1 - 2.89741816e-5 * t + 1.61456053e-7 * t * t)
    d = 2 * u - 8 * v + 4
    x, y = 3 * u / d, 2 * v / d
    rgb = XYZ_TO_SRGB @ np.array([x / y, 1.0, (1 - x - y) / y])
    return np.asarray(rgb / rgb[1], dtype=np.float64)


def white_balance_gains(light_k: float, white_balance_k: float) -> NDArray[np.float64]:
    """Each channel's gain ``(r, 1, b)`` of an image of a light of CCT ``light_k`` taken by a camera
    white-balanced for ``white_balance_k``: the light's white over the balance's white, channel by
    channel (a camera's white balance is one gain per channel, set so that a grey surface under
    its own white shows grey), normalised to green (which keeps the brightness gain).

    The gains scale the pixel values as the brightness gain does: the rendered ceiling's values are
    taken as linear in the light, as by a camera without gamma encoding.
    """
    return cct_white_rgb(light_k) / cct_white_rgb(white_balance_k)


def grey_world_gains(gains: ArrayLike, means: Sequence[float]) -> NDArray[np.float64]:
    """The channel gains after a grey-world auto white balance (Buchsbaum 1980): ``gains`` (one, or
    ``(3,)``: the brightness and the light's raw colour) scaled per channel so that the frame, whose
    channel means before them are ``means``, has equal means: ``gains[1] means[1] / means[c]`` for channel
    ``c``, green keeping its gain. The light's colour cancels when it lies evenly over the frame; what
    is left is the scene's own mean colour, which the balance takes for the light's. A channel with a
    zero mean leaves the gains as they are."""
    g = np.broadcast_to(np.asarray(gains, dtype=np.float64), (3,))
    raw = g * np.asarray(means[:3], dtype=np.float64)
    if not (raw > 0).all():
        return np.array(g)
    return np.asarray(g * raw[1] / raw, dtype=np.float64)


def check_light(
    white_balance_k: float, cct_k: tuple[float, float], daylight_cct_k: tuple[float, float], auto: bool, where: str
) -> None:
    """Check the light's colour fields of ``where`` (a camera config), naming the field and value."""
    lo, hi = CCT_RANGE_K
    check(len(cct_k) == 2, f"{where}.cct_k must be [under the panels, between them] in K, got {cct_k!r}")
    check(
        not (auto and white_balance_k),
        f"{where}.white_balance_k {white_balance_k:g} and auto_white_balance: give one of the two (0: the fixed one off)",
    )
    if white_balance_k == 0 and not auto:
        check(
            tuple(cct_k) == (0.0, 0.0),
            f"{where}.cct_k {list(cct_k)} needs white_balance_k (0: the light's colour is off); "
            f"give white_balance_k in {lo:g}..{hi:g} K, or auto_white_balance",
        )
    check(
        white_balance_k == 0 or lo <= white_balance_k <= hi,
        f"{where}.white_balance_k must be 0 (off) or in {lo:g}..{hi:g} K, got {white_balance_k!r}",
    )
    if tuple(cct_k) != (0.0, 0.0):
        for value in cct_k:
            check(lo <= value <= hi, f"{where}.cct_k must lie in {lo:g}..{hi:g} K, got {list(cct_k)}")
    check(len(daylight_cct_k) == 2, f"{where}.daylight_cct_k must be [lowest, highest] in K, got {daylight_cct_k!r}")
    if tuple(daylight_cct_k) != (0.0, 0.0):
        check(
            lo <= daylight_cct_k[0] <= daylight_cct_k[1] <= hi,
            f"{where}.daylight_cct_k must be [lowest, highest] within {lo:g}..{hi:g} K, got {list(daylight_cct_k)}",
        )
        check(
            tuple(cct_k) != (0.0, 0.0), f"{where}.daylight_cct_k {list(daylight_cct_k)} needs cct_k (the light under the panels)"
        )
