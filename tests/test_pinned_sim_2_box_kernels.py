"""Per-fragment boxes (`sim.boxes`): the band-mass P2G gives each fragment's box the mass of
its band particles (the weights of a stencil sum to one), and the mass gradient the latched-normal contact reads
is the central difference of the box's nodal masses with zero beyond the box, on every axis and at the box's
faces. Small scenes (2,000 particles on a 24³ grid)."""

import torch
import warp as wp
from simutil import box_gradient, zero_padded_gradient

from fracture_gs.runtime import ensure_warp
from fracture_gs.sim.boxes.fragment_boxes import FragmentBoxes
from fracture_gs.sim.clock import FrameClock
from fracture_gs.sim.storage import N_COUNTS

n, N = 24, 2000


def _deposit(band_every=0):
    """Two fragments (x < ½, x ≥ ½) of particles at rest in [0.3, 0.7]³, deposited into their boxes; with
    `band_every`, every such particle is a band particle (band flags passed to P2G)."""
    ensure_warp()
    g = torch.Generator().manual_seed(3)
    x = 0.3 + 0.4 * torch.rand(N, 3, generator=g)
    fragment = (x[:, 0] >= 0.5).to(torch.int32)
    mass = 0.5 + torch.rand(N, generator=g)
    band = torch.zeros(N, dtype=torch.int32)
    if band_every:
        band[::band_every] = 1
    P = {
        "x": x,
        "v": torch.zeros(N, 3),
        "C": torch.zeros(N, 3, 3),
        "mass": mass,
        "volume": torch.full((N,), 1e-5),
        "stress": torch.zeros(N, 3, 3),
        "fragment": fragment,
    }
    types = {"x": wp.vec3, "v": wp.vec3, "C": wp.mat33, "stress": wp.mat33}
    w = {k: wp.from_torch(t.contiguous(), dtype=types.get(k)) for k, t in P.items()}
    c = FrameClock("cpu", 0)
    c.set(1e-3, [0.0])
    boxes = FragmentBoxes((n, n, n), (0.0, 0.0, 0.0), 1.0 / n, "cpu")
    boxes.fit(x, fragment)
    counts = torch.zeros(N_COUNTS, dtype=torch.int32)
    flags = wp.from_torch(band) if band_every else None
    boxes.p2g(w, c.view, wp.from_torch(counts), band_flags=flags)
    return boxes, P, band


def test_band_p2g_gives_each_box_its_band_particles_mass():
    """With band flags, each fragment's box holds Σ m_p of its band particles as band mass (every third particle
    here) and Σ m_p of all its particles as mass: quadratic B-spline weights sum to one per particle."""
    boxes, P, band = _deposit(band_every=3)
    for k in range(2):
        a, b = int(boxes.offset[k]), int(boxes.offset[k + 1])
        mine = P["fragment"] == k
        want_band = float(P["mass"][mine & (band != 0)].double().sum())
        want_mass = float(P["mass"][mine].double().sum())
        assert abs(float(boxes.band[a:b].double().sum()) - want_band) < 1e-4 * want_band
        assert abs(float(boxes.mp[a:b, 3].double().sum()) - want_mass) < 1e-4 * want_mass


def test_box_mass_gradient_is_the_central_difference_with_zero_beyond_the_box():
    """∇m^k at every node of box k is (m[i+1] − m[i−1]) / 2Δx per axis, a node outside the box counting as
    massless: compared with torch's central differences of the box's zero-padded mass array, on all three axes
    (including the faces, where only one neighbour lies inside)."""
    boxes, _, _ = _deposit()
    for k in range(2):
        d = [int(v) for v in boxes.dims[k]]
        a = int(boxes.offset[k])
        want = zero_padded_gradient(boxes.mp[a : a + d[0] * d[1] * d[2], 3].double().reshape(d), n)
        got = box_gradient(boxes, k)
        scale = float(want.abs().max())
        assert scale > 0
        assert float((got - want).abs().max()) < 1e-5 * scale
