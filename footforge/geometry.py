"""Geometry shared by several packages."""

from __future__ import annotations

import numpy as np

BOX_CORNER_SIGNS = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], dtype=float)
"""The eight corners of the unit box [-1, 1]^3."""


def box_corners(half_sizes, centre=0.0) -> np.ndarray:
    """(8, 3) corners of the box with these half sizes about `centre`, in the box's frame."""
    return np.asarray(centre, dtype=float) + BOX_CORNER_SIGNS * np.asarray(half_sizes, dtype=float)
