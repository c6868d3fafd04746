"""The surface measure in Warp (`penetration_kernels`) against its torch twins and the closed form it inverts.

Inversion: for every share c in [0, 1] `depth_from_share` returns the u in [−1, 1] with F(u) = c, F the kernel's
half-space share, to the bisection's 2⁻⁴⁰; shares outside [0, 1] read as the nearest end. Sums: the walk of the
cells around each query gives the depth and the piece of `penetration.behind_surfaces_torch`'s pairs."""

import pytest
import torch

from fracture_gs.sim.diagnostics import penetration as pen
from fracture_gs.sim.diagnostics import penetration_kernels as pk
from fracture_gs.sim.diagnostics.penetration import depth_from_fraction, fraction_of_half_space
from fracture_gs.sim.diagnostics.penetration_kernels import depth_from_share


def test_the_kernel_inverts_the_half_space_share(device):
    """u → F(u) → depth_from_share gives u back within 1e-11 for |u| ≤ 0.95; towards the ends F flattens
    (F′ ∝ (1 − u²)², so a share one rounding from 1 is a cube root of it, ≈ 1e-5, from u = 1) and u comes back
    within 1e-4. F of the returned u is the share asked for everywhere."""
    u = torch.linspace(-1, 1, 4001, dtype=torch.float64, device=device)
    back = depth_from_share(fraction_of_half_space(u))
    inner = u.abs() <= 0.95
    torch.testing.assert_close(back[inner], u[inner], rtol=0, atol=1e-11)
    torch.testing.assert_close(back, u, rtol=0, atol=1e-4)
    c = torch.rand(5000, dtype=torch.float64, generator=torch.Generator().manual_seed(4)).to(device)
    torch.testing.assert_close(fraction_of_half_space(depth_from_share(c)), c, rtol=0, atol=1e-11)


def test_the_kernel_matches_its_torch_twin(device):
    """Same bisection, same polynomial: the Warp kernel and the torch twin agree to 1e-12 where F is steep enough
    to tell u apart (shares of |u| ≤ 0.95, the half-full ball u = 0 included); towards the ends, where F flattens
    and the two may round its powers differently (a GPU contracts a·b + c into one rounding), both return a u whose
    share is the one asked for."""
    c = torch.cat([torch.rand(3000, dtype=torch.float64), torch.tensor([0.0, 0.5, 1.0, 1e-300, 1 - 1e-16])]).to(device)
    u, u0 = depth_from_share(c), depth_from_fraction(c)
    steep = (c >= fraction_of_half_space(torch.tensor(-0.95))) & (c <= fraction_of_half_space(torch.tensor(0.95)))
    torch.testing.assert_close(u[steep], u0[steep], rtol=0, atol=1e-12)
    torch.testing.assert_close(u, u0, rtol=0, atol=1e-4)
    torch.testing.assert_close(fraction_of_half_space(u), c.clamp(0, 1), rtol=0, atol=1e-10)
    assert abs(float(depth_from_share(torch.tensor([0.5], dtype=torch.float64, device=device)))) < 1e-12


def test_shares_outside_the_unit_range_read_as_its_ends():
    """A share above 1 (rounding in a sum of kernel weights) is a ball filled: u at 1 (F(u) = 1), depth R; below 0:
    u at −1 (F(u) = 0) — where F is flat, within 1e-4 of the end."""
    out = depth_from_share(torch.tensor([1.5, 1.0 + 1e-9, -0.25, -1e-12], dtype=torch.float64))
    torch.testing.assert_close(out, torch.tensor([1.0, 1.0, -1.0, -1.0], dtype=torch.float64), rtol=0, atol=1e-4)
    ends = torch.tensor([1.0, 1.0, 0.0, 0.0], dtype=torch.float64)
    torch.testing.assert_close(fraction_of_half_space(out), ends, rtol=0, atol=1e-12)


def test_no_share_is_no_launch_and_no_error():
    """An empty frame (no particle behind another piece) returns an empty float64 tensor."""
    out = depth_from_share(torch.zeros(0, dtype=torch.float64))
    assert out.shape == (0,) and out.dtype == torch.float64


def test_a_float32_share_is_inverted_in_float64():
    """Shares given in float32 are inverted in float64 (the depth keeps the bisection's resolution)."""
    c = torch.tensor([0.25, 0.75], dtype=torch.float32)
    out = depth_from_share(c)
    assert out.dtype == torch.float64
    torch.testing.assert_close(out, depth_from_fraction(c.double()), rtol=0, atol=1e-12)


def _pressed(depth_spacings: float, seed: int, third: bool = False) -> tuple[torch.Tensor, torch.Tensor]:
    """Two jittered 14³ blocks (spacing 0.02 m) pressed into each other along x by `depth_spacings` spacings; with
    `third` a third block (id 2) pressed into block 0 from the other side by the same depth (a tie in depth)."""
    g = torch.Generator().manual_seed(seed)
    s, n = 0.02, 14
    starts = [0.0, n * s - depth_spacings * s] + ([-(n * s) + depth_spacings * s] if third else [])
    parts, ids = [], []
    for k, x0 in enumerate(starts):
        axes = [torch.arange(n) * s + x0, torch.arange(n) * s, torch.arange(n) * s]
        p = torch.stack(torch.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3).double()
        parts.append(p + 0.2 * s * (torch.rand(p.shape, generator=g, dtype=torch.float64) - 0.5))
        ids.append(torch.full((len(p),), k, dtype=torch.long))
    return torch.cat(parts), torch.cat(ids)


def _on(device, x, frag):
    return x.to(device), frag.to(device)


def _calibration(x, frag, K):
    cal = pen.calibrate(x[frag == 0], frag[frag == 0])  # one block alone: the scales at a latch
    cal["filled"] = cal["filled"].repeat(K)
    return cal


@pytest.mark.parametrize("depth_spacings, seed", [(0.0, 0), (1.5, 1), (3.0, 2)])
def test_the_warp_sums_match_the_torch_twin(depth_spacings, seed, device):
    """Pieces pressed together by 0, 1.5 and 3 spacings, each particle weighted by a volume change: the Warp walk of
    the cells gives every particle the depth and the piece of the twin's pairs (float32 offsets there: within 1e-6
    of the kernel radius), and deeper pressing reads deeper."""
    x, frag = _on(device, *_pressed(depth_spacings, seed))
    cal = _calibration(x, frag, 2)
    J = 1.0 + 0.1 * torch.rand(len(x), dtype=torch.float64, generator=torch.Generator().manual_seed(seed)).to(device)
    depth, into = pen.surface_depth(x, frag, cal, J)
    depth0, into0 = pen.surface_depth(x, frag, cal, J, twin=True)
    torch.testing.assert_close(depth, depth0, rtol=0, atol=1e-6 * cal["radius"])
    assert torch.equal(into, into0)
    if depth_spacings > 0:
        assert float(depth.max()) > 0.5 * depth_spacings * 0.02 * 0.5, "pressed pieces read a depth"


def test_a_tie_in_depth_names_the_larger_piece_and_unlabelled_or_uncalibrated_ids_are_skipped(device):
    """Block 0 pressed by blocks 1 and 2 from both sides: each of its particles is behind the piece it is deepest
    in, as the twin says (ties: the larger id). Particles with id −1 or an id the calibration lacks are neither
    measured nor counted as another piece's volume."""
    x, frag = _on(device, *_pressed(2.0, 3, third=True))
    cal = _calibration(x, frag, 3)
    depth, into = pen.surface_depth(x, frag, cal)
    depth0, into0 = pen.surface_depth(x, frag, cal, twin=True)
    torch.testing.assert_close(depth, depth0, rtol=0, atol=1e-6 * cal["radius"])
    assert torch.equal(into, into0) and set(into[frag == 0].unique().tolist()) >= {1, 2}
    hidden = frag.clone()
    hidden[frag == 2] = -1  # unlabelled: piece 2 is not there for the measure
    d_hidden, into_hidden = pen.surface_depth(x, hidden, cal)
    cal2 = _calibration(x, frag, 2)  # calibrated for ids 0 and 1 only: id 2 is not evaluated either
    d_short, into_short = pen.surface_depth(x, frag, cal2)
    for d, i in ((d_hidden, into_hidden), (d_short, into_short)):
        assert not bool((i == 2).any()) and float(d[frag == 2].abs().max()) == 0.0
        torch.testing.assert_close(
            d, pen.surface_depth(x, hidden, cal, twin=True)[0], rtol=0, atol=1e-6 * cal["radius"]
        )


def test_queries_in_chunks_read_as_in_one(device):
    """The sums held for a few queries at a time (chunks of 7) give every query the same depth, bit for bit, as all
    at once: each query's sum is its own thread's."""
    x, frag = _on(device, *_pressed(2.0, 4))
    cal = _calibration(x, frag, 2)
    lo = x.min(0).values
    cells = pen._Cells(x, frag, lo, cal["radius"] / 3)
    query = torch.arange(len(x), device=device)
    off = pen._cube(3, x.device, ball=True)
    J = torch.ones(len(x), dtype=torch.float64, device=device)
    args = (x, frag, J, cal["filled"], cal["radius"], cells, off, query, pen._BITS)
    a = pk.deepest_behind_surfaces(*args, 7)
    b = pk.deepest_behind_surfaces(*args, len(x))
    assert torch.equal(a[0], b[0]) and torch.equal(a[1], b[1]) and float(a[0].max()) > 0


def test_an_exact_tie_names_the_larger_piece_as_the_twin_does(device):
    """A particle with one particle of piece 1 and one of piece 2 at the same distance, each filling its ball (a
    tiny filled density makes every share 1, so both depths are the same, about R): it lies behind piece 2, the
    larger id, in the kernel as in the twin (their depths agree to where F is flat at u = 1)."""
    x = torch.tensor([[0.0, 0.0, 0.0], [0.005, 0.0, 0.0], [-0.005, 0.0, 0.0]], dtype=torch.float64, device=device)
    frag = torch.tensor([0, 1, 2], device=device)
    filled = torch.full((3,), 1e-3, dtype=torch.float64, device=device)
    cal = {"radius": 0.05, "filled": filled, "spacing": 0.05 / pen.SPACINGS}
    depth, into = pen.surface_depth(x, frag, cal)
    depth0, into0 = pen.surface_depth(x, frag, cal, twin=True)
    assert int(into[0]) == 2 and int(into0[0]) == 2
    torch.testing.assert_close(depth, depth0, rtol=0, atol=1e-4 * 0.05)
    assert torch.equal(into, into0)


def test_near_another_piece_is_a_strict_distance_to_a_labelled_other_piece(device):
    """A query is near another piece when a particle of another piece (id ≥ 0) lies closer than the reach: at 0.9
    of it yes, at 1.1 no, a particle of its own piece or an unlabelled one at any distance never."""
    reach = 0.01
    x = torch.tensor(
        [
            [0, 0, 0],
            [0.009, 0, 0],
            [0.5, 0, 0],
            [0.5, 0.011, 0],
            [1, 0, 0],
            [1, 0, 0.002],
            [1.5, 0, 0],
            [1.5, 0.003, 0],
        ],
        dtype=torch.float64,
        device=device,
    )
    frag = torch.tensor([0, 1, 0, 1, 0, 0, 0, -1], device=device)
    cells = pen._Cells(x, frag, x.min(0).values, reach)
    query = torch.tensor([0, 2, 4, 6], device=device)
    near = pk.near_another_piece_mask(x, frag, cells, query, reach, pen._BITS)
    assert near.tolist() == [True, False, False, False]


def test_near_another_piece_matches_the_torch_pairs(device):
    """On pressed blocks the kernel marks exactly the candidates the twin's pair gather keeps."""
    x, frag = _on(device, *_pressed(1.0, 5))
    reach = 1.2 * 0.02
    cells = pen._Cells(x, frag, x.min(0).values, reach)
    query = torch.arange(len(x), device=device)
    qi, j = cells.gather(cells.coord[query], 1)
    close = (frag[j] != frag[query][qi]) & (frag[j] >= 0) & (((x[query][qi] - x[j]) ** 2).sum(1) < reach**2)
    expected = torch.zeros(len(x), dtype=torch.bool, device=device).index_fill_(0, qi[close], True)
    near = pk.near_another_piece_mask(x, frag, cells, query, reach, pen._BITS)
    assert torch.equal(near, expected) and 0 < int(near.sum()) < len(x)
