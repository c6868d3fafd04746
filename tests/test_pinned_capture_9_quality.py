"""The two measures a capture's targets are stated in (`capture.quality`), pinned on hand-built images and id
arrays with values worked out by hand: `edge_strength` (background = median colour of all four image edges,
object = pixels whose summed |RGB − background| is above 0.12, grey = mean of R, G, B, forward differences) and
`pieces` (fragments holding at least `share` of all particles, unassigned ones included, largest first)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from fracture_gs.capture.quality import edge_strength, pieces

LOW, HIGH = 0.2, 0.8  # the two grey levels of the split image


def split_image(k: int) -> np.ndarray:
    """An 8×8 grey image, columns 0–3 at LOW and 4–7 at HIGH, turned k quarter turns."""
    g = np.full((8, 8), LOW)
    g[:, 4:] = HIGH
    return np.repeat(np.rot90(g, k)[..., None], 3, axis=2).copy()


@pytest.mark.parametrize("k", [0, 1, 2, 3])
def test_every_image_edge_votes_for_the_background(k):
    """Half the image LOW, half HIGH: the four edges hold 16 pixels of each, so their median is the mid-grey
    0.5 and every pixel (0.3 from it in each channel, 0.9 summed) is the object. The 7 forward differences
    across the split are |HIGH − LOW| = 0.6 among the 7×7 pixels that have both, so the strength is 0.6/7.
    Reading any edge twice or a row/column one in from the edge tips the median to one half: the strength
    would then be 0 (the flat half) or 0.6·7/28 (the other half), in every orientation of the split."""
    assert edge_strength(split_image(k)) == pytest.approx(0.6 / 7, rel=1e-12)


def test_uint8_images_are_read_as_fractions_of_255():
    """The split image stored as uint8 (51 and 204 = 0.2 and 0.8 of 255) measures the same 0.6/7 as its float
    twin: a byte is divided by 255, not by any other scale."""
    img = np.round(split_image(0) * 255).astype(np.uint8)
    assert set(np.unique(img).tolist()) == {51, 204}
    assert edge_strength(img) == pytest.approx(0.6 / 7, rel=1e-12)


@pytest.mark.parametrize("dtype", [np.uint8, np.float64])
def test_an_alpha_channel_is_ignored(dtype):
    """An RGBA image measures as its RGB part: alpha 0 on the LOW half and opaque on the HIGH half would move
    both the grey level and the background if it were read, but the strength stays 0.6/7."""
    rgb = split_image(0)
    alpha = np.where(rgb[..., :1] > 0.5, 1.0, 0.0)
    img = np.concatenate([rgb, alpha], axis=2)
    if dtype is np.uint8:
        img = np.round(img * 255).astype(np.uint8)
    assert edge_strength(img) == pytest.approx(0.6 / 7, rel=1e-12)


def square(rgb) -> np.ndarray:
    """An 8×8 black float image with a 4×4 square of colour `rgb` at rows and columns 2–5."""
    img = np.zeros((8, 8, 3))
    img[2:6, 2:6] = rgb
    return img


def square_strength(grey: float) -> float:
    """Edge strength of `square` with grey level `grey` (the mean of its RGB): of the 16 object pixels, the
    three on the right column and three on the bottom row (corner excluded) have one forward difference of
    `grey`, the corner (5, 5) has two (√2·grey), the other 9 none."""
    return (6 + math.sqrt(2)) * grey / 16


def test_grey_is_the_mean_of_the_three_channels():
    """A pure red square on black is the object (summed difference 1 > 0.12) and its grey level is 1/3 (the mean
    of R, G, B), so the strength is (6 + √2)/48; a white square of grey 1 measures three times that."""
    assert edge_strength(square((1.0, 0.0, 0.0))) == pytest.approx(square_strength(1 / 3), rel=1e-12)
    assert edge_strength(square((1.0, 1.0, 1.0))) == pytest.approx(square_strength(1.0), rel=1e-12)


def test_a_pixel_is_object_only_above_a_summed_difference_of_0_12():
    """The object is the pixels whose |RGB − background| summed over the channels is strictly above 0.12: a
    square of grey 0.13/3 is the object (strength (6 + √2)·grey/16), one of 0.11/3 is not (0), and a red of
    exactly 0.12 in one channel is not either."""
    assert edge_strength(square((0.13 / 3,) * 3)) == pytest.approx(square_strength(0.13 / 3), rel=1e-12)
    assert edge_strength(square((0.11 / 3,) * 3)) == 0.0
    assert edge_strength(square((0.12, 0.0, 0.0))) == 0.0
    assert edge_strength(square((0.121, 0.0, 0.0))) == pytest.approx(square_strength(0.121 / 3), rel=1e-12)


def test_an_object_without_forward_differences_has_no_strength():
    """An object only in the last row and column (a white corner pixel, or white pixels on the last row and
    column, on black) has no pixel with both forward differences, so its strength is 0, as for a blank image."""
    img = np.zeros((8, 8, 3))
    img[7, 7] = 1.0
    assert edge_strength(img) == 0.0
    img = np.zeros((8, 8, 3))
    img[3, 7] = 1.0  # the last column: no right neighbour, so no horizontal difference
    img[7, 3] = 1.0
    assert edge_strength(img) == 0.0
    assert edge_strength(np.zeros((8, 8, 3), dtype=np.uint8)) == 0.0


def test_pieces_take_three_percent_by_default_inclusive():
    """With the default share 3 %, of 100 particles a fragment of exactly 3 is a piece and one of 2 is not;
    the result lists the pieces' counts largest first, whatever their ids."""
    f = np.array([4] * 3 + [0] * 30 + [7] * 60 + [2] * 2 + [-1] * 5)
    assert pieces(f) == [60, 30, 3]
    assert pieces(f, 0.0) == [60, 30, 3, 2]
    assert pieces(f, 0.3) == [60, 30]
    assert pieces(f, 0.31) == [60]


def test_unassigned_particles_count_in_the_total():
    """The share is of all particles, −1 (no fragment) included: fragments of 4 and 3 among 100 particles, 93
    unassigned, hold 4 % and 3 %, so at share 4 % only the 4 is a piece (of the assigned 7 both would be)."""
    f = np.array([0] * 4 + [1] * 3 + [-1] * 93)
    assert pieces(f, 0.04) == [4]
    assert pieces(f, 0.03) == [4, 3]


def test_no_fragment_means_no_piece():
    """All particles unassigned, or none at all, is no piece; fragments all under the share are none either."""
    assert pieces(np.full(10, -1)) == []
    assert pieces(np.zeros(0, dtype=np.int64)) == []
    assert pieces(np.array([0, 1, 2, 3]), 0.5) == []
