"""Pinned rule of the fit's heading (`capture.fit.fit_transform`), round ten: the longest horizontal principal
axis goes onto x for any object that has one, two Gaussians included (the line between them is that axis), so
the fitted size is their distance, not the larger of its x and y shadows; one Gaussian, or many at one point,
has no size and is a SceneError naming the count.
"""

from __future__ import annotations

import pytest
import torch

from fracture_gs.capture.fit import CENTRE, fit_transform
from fracture_gs.errors import SceneError

F64 = torch.float64


@pytest.mark.parametrize(
    "pair, up, height",
    [
        ([[0.0, 0.0, 0.0], [3.0, 4.0, 0.0]], [0.0, 0.0, 1.0], 0.0),
        ([[1.0, 2.0, 1.0], [-2.0, 4.0, 5.0]], [0.0, -1.0, 0.0], 2.0),
    ],
    ids=["level, up +z", "tilted, up -y"],
)
def test_a_pair_of_gaussians_is_laid_along_x(pair, up, height):
    """Two Gaussians 5 apart across the up axis (a 3-4-5 triangle), level or 2 apart along it: the fit takes
    the line between them onto ±x and keeps up on +z, so the fitted pair is size = 0.5 m long in x, 0 wide in
    y and 2 · 0.1 tall, the scale is 0.5/5 = 0.1 and its bounding box is centred on CENTRE. Left unturned,
    the level pair would be 4 long in y and scaled by 0.5/4."""
    x = torch.tensor(pair, dtype=F64)
    u = torch.tensor(up, dtype=F64)
    t = fit_transform(x, u, 0.5)
    assert t.scale == pytest.approx(0.1, rel=1e-12)
    assert (t.rotation @ u).tolist() == pytest.approx([0.0, 0.0, 1.0], abs=1e-12)
    y = t.points(x)
    d = y[1] - y[0]
    assert abs(float(d[0])) == pytest.approx(0.5, abs=1e-12) and float(d[1]) == pytest.approx(0.0, abs=1e-12)
    assert abs(float(d[2])) == pytest.approx(0.1 * height, abs=1e-12)
    centre = 0.5 * (y.max(0).values + y.min(0).values)
    assert centre.tolist() == pytest.approx(list(CENTRE), abs=1e-12)


@pytest.mark.parametrize("n", [1, 4])
def test_gaussians_at_one_point_have_no_size(n):
    """One Gaussian, or four at one point, cannot be fitted to a size: a SceneError naming how many there are
    and the way out."""
    with pytest.raises(SceneError) as info:
        fit_transform(
            torch.full((n, 3), 2.0, dtype=F64), torch.tensor([0.0, 0.0, 1.0], dtype=F64), 0.5, source="s.ply: "
        )
    assert str(info.value) == (
        f"s.ply: the object's {n} Gaussians all lie at one point after clean-up, so it has no size to fit; check the "
        "scene file (a captured object has an extent), or set capture.fit = false to use it as written."
    )


def test_no_gaussians_is_one_sentence_not_an_index_error():
    """fit_transform of an empty point set (a clean-up or ROI that removed everything, called directly) refuses
    with a SceneError that says nothing is left and where to look, not torch's reduction error."""
    with pytest.raises(SceneError) as info:
        fit_transform(torch.zeros((0, 3), dtype=F64), torch.tensor([0.0, 0.0, 1.0], dtype=F64), 0.5, source="s.ply: ")
    assert str(info.value) == (
        "s.ply: the object has no Gaussians left after clean-up, so there is nothing to fit; check the scene file "
        "and the clean-up and ROI keys of [capture] (they may remove everything)."
    )
