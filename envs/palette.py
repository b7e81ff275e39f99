"""The landmarks' colours in the top view, shared by the renderer and the sensors' drawing.

:mod:`envs.render` paints a landmark in its colour while the camera sees it (grey otherwise);
a sensor's ``draw`` (the bearing camera's distractors) uses the same colour for what imitates
it. Both import this module, which imports nothing of the package: the sensors are loaded with
the world config, which the renderer imports, so the colours cannot live in the renderer.
"""

from __future__ import annotations

Color = tuple[int, int, int]

HIDDEN_LANDMARK: Color = (128, 128, 128)
LANDMARK_PALETTE: tuple[Color, ...] = (
    (255, 215, 0),
    (0, 170, 255),
    (255, 100, 180),
    (255, 140, 0),
    (150, 90, 255),
    (0, 220, 200),
    (255, 60, 60),
    (190, 255, 80),
)


def landmark_color(index: int) -> Color:
    """Colour of landmark ``index`` while it is visible."""
    return LANDMARK_PALETTE[index % len(LANDMARK_PALETTE)]
