"""Pinned rule of `capture.quality.edge_strength`, round seventeen: the background is the median colour of the
image's outermost ring (first and last row, first and last column), not of any inner row. An image whose
outermost rows are black and whose inner rows are white is a white band on black: the band is the object.

8 × 8 image, rows 0 and 7 black, rows 1..6 white (full width). Ring: rows 0 and 7 give 16 black pixels, the two
columns 2 black and 6 white each, so 20 black against 12 white: background black. Object pixels (rows 1..6,
minus the last row and column of the gradient grid): rows 1..6 × columns 0..6, 42 pixels; the grey step is 1 only
between rows 6 and 7, so 7 of them carry |∇I| = 1: edge strength 7 / 42 = 1/6. Taking row 1 or row 6 as the
border instead turns the median white and the object into the two black rows (strength 1).
"""

from __future__ import annotations

import numpy as np
import pytest

from fracture_gs.capture.quality import edge_strength


def band(dtype=np.float64, flip: bool = False) -> np.ndarray:  # [8, 8, 3]
    img = np.zeros((8, 8, 3), dtype=np.float64)
    img[1:7] = 1.0
    if flip:
        img = img.transpose(1, 0, 2).copy()
    return (img * 255).astype(np.uint8) if dtype == np.uint8 else img


def test_a_white_band_between_black_outer_rows_is_the_object():
    """Background = median of the outermost ring (black here, 20 of 32 ring pixels), so the white band is the
    object and the strength is 7 / 42 = 1/6 (float and uint8 alike)."""
    assert edge_strength(band()) == pytest.approx(1 / 6, rel=1e-12)
    assert edge_strength(band(np.uint8)) == pytest.approx(1 / 6, rel=1e-12)


def test_a_white_band_between_black_outer_columns_is_the_object():
    """The same band turned a quarter: columns 0 and 7 black. Object pixels columns 1..6 × rows 0..6 (42), the
    horizontal step 1 only between columns 6 and 7 (7 pixels): 1/6 again, the ring's columns count as much as its
    rows."""
    assert edge_strength(band(flip=True)) == pytest.approx(1 / 6, rel=1e-12)
