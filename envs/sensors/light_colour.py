"""The colour of light in the ceiling camera's images: a light's colour temperature against the
camera's white balance, one gain per channel (:class:`envs.sensors.ceiling_camera.CeilingCameraConfig`'s
``white_balance_k`` and ``cct_k``; issue 30)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

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
