"""The ceiling pipeline's fast paths give what the plain computations give, bit for bit (they
do less work for the same estimates): line blobs from the box around the mask, the cells' tint, the plan's
rectangle distances."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from localizers.ceiling_target import vision


def _plain_blobs(mask: np.ndarray, min_px: int) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Connected components of the whole mask, as the pipeline read them before it cropped."""
    count, labels, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
    out = []
    for k in range(1, count):
        if stats[k, cv2.CC_STAT_AREA] < min_px:
            continue
        rows, cols = np.nonzero(labels == k)
        pts = np.stack([cols + 0.5, rows + 0.5], axis=1).astype(np.float64)
        centre, direction = vision.fit_line(pts)
        out.append((pts, centre, direction))
    return out


def _random_mask(rng: np.random.Generator, shape: tuple[int, int], speckle: float) -> np.ndarray:
    mask = np.zeros(shape, np.uint8)
    h, w = shape
    for _ in range(int(rng.integers(1, 12))):
        x0, y0, angle = int(rng.integers(0, w)), int(rng.integers(0, h)), rng.uniform(0, np.pi)
        length, width = int(rng.integers(3, 120)), int(rng.integers(1, 8))
        cv2.line(mask, (x0, y0), (int(x0 + length * np.cos(angle)), int(y0 + length * np.sin(angle))), 255, width)
    mask[rng.random(shape) < speckle] = 255
    return mask


@pytest.mark.parametrize("threads", [1, 2])
def test_line_blobs_from_the_box_around_the_mask_are_the_whole_masks_in_the_same_order(threads: int) -> None:
    """Odd boxes, odd image sizes, speckle (hundreds of components) and both thread counts: the
    cropped labelling must number the components as the whole image's does (OpenCV labels 2 x 2
    blocks; a box on an odd row reorders them, which this test catches)."""
    before = cv2.getNumThreads()
    cv2.setNumThreads(threads)
    try:
        rng = np.random.default_rng(threads)
        blobs = 0
        for trial in range(300):
            shape = (240, 320) if trial % 2 else (int(rng.integers(20, 400)), int(rng.integers(20, 400)))
            mask = _random_mask(rng, shape, rng.uniform(0.0, 0.03) if trial % 3 == 0 else 0.0)
            min_px = 4 + trial % 30
            plain, fast = _plain_blobs(mask, min_px), vision._line_blobs(mask, min_px)
            assert len(fast) == len(plain)
            for (pts, centre, direction), blob in zip(plain, fast):
                assert np.array_equal(blob.points, pts)
                assert np.array_equal(blob.centre, centre) and np.array_equal(blob.direction, direction)
            blobs += len(plain)
        assert blobs > 1000
    finally:
        cv2.setNumThreads(before)


def test_cell_tint_and_rectangle_distances_equal_the_plain_numpy_forms() -> None:
    rng = np.random.default_rng(0)
    for _ in range(20):
        image = rng.integers(0, 256, size=(240, 320, 3), dtype=np.uint8)
        small = cv2.resize(image, (80, 60), interpolation=cv2.INTER_AREA).astype(np.float64)
        value = small.max(axis=2)
        saturation, got_value = vision.cell_tint(image, 4)
        assert np.array_equal(got_value, value.ravel())
        assert np.array_equal(saturation, ((value - small.min(axis=2)) / np.maximum(value, 1.0)).ravel())
    for _ in range(50):
        dx, dy = rng.normal(size=500) * 2, rng.normal(size=500) * 2
        dx[:20], dy[:20] = 0.25, rng.choice([0.2, -0.2, 0.0, 0.5], 20)  # on the edges and corners
        hx, hy = float(rng.uniform(0, 1)), float(rng.uniform(0, 1))
        ox, oy = np.abs(dx) - hx, np.abs(dy) - hy
        plain = np.where((ox <= 0) & (oy <= 0), np.maximum(ox, oy), np.hypot(np.maximum(ox, 0.0), np.maximum(oy, 0.0)))
        assert np.array_equal(vision._rect_distance(dx, dy, hx, hy), plain)
