"""Hand-written bug campaign, round three: the Python API's per-particle parameter checks (`sim.particles`).

Each parameter accepts the edge of its range and refuses the first value past it, with a SimulationError that
names it: E, mass, volume, yield_stress, sigma_R > 0; ν ∈ [0, 0.5); hardening ≥ 0; friction_angle ≥ 0 (φ = 0 gives
the Drucker–Prager cone of slope α = 0, a legal material).
"""

import pytest
import torch

from fracture_gs import sim as S
from fracture_gs.errors import SimulationError

X = torch.tensor([[0.1, 0.2, 0.3], [0.2, 0.2, 0.3]])

# (argument, a value on the edge of its range that is accepted, the first value past it that is refused)
EDGES = [
    ("friction_angle", 0.0, -1.0),
    ("hardening", 0.0, -1e-3),
    ("nu", 0.0, -1e-3),
    ("E", 1e-3, 0.0),
    ("mass", 1e-6, 0.0),
    ("volume", 1e-9, 0.0),
    ("yield_stress", 1e-3, 0.0),
    ("sigma_R", 1e-3, 0.0),
]


@pytest.mark.parametrize("name,edge,past", EDGES, ids=[e[0] for e in EDGES])
def test_each_parameter_takes_its_edge_and_refuses_past_it(name, edge, past):
    """The edge value builds Particles holding it; one step past raises a SimulationError naming the argument."""
    p = S.Particles(x=X, **{name: edge})
    if name == "friction_angle":
        assert torch.equal(p.alpha, torch.zeros(2)), "φ = 0 is the cone of slope α = 0"
    else:
        assert torch.all(getattr(p, name) == edge)
    with pytest.raises(SimulationError, match=name):
        S.Particles(x=X, **{name: past})


def test_poisson_ratio_just_below_a_half_is_taken_and_a_half_is_refused():
    """ν ∈ [0, 0.5): 0.4999 builds, 0.5 (incompressible: λ infinite) raises naming nu."""
    assert float(S.Particles(x=X, nu=0.4999).nu[0]) == pytest.approx(0.4999)
    with pytest.raises(SimulationError, match="nu"):
        S.Particles(x=X, nu=0.5)


def test_every_material_key_reaches_the_particles_from_the_default_and_from_a_map_entry():
    """`material_arrays` gives each particle every [material] parameter: label 0 (no map entry) the default's,
    label 3 its map entry's, for each of model, E, ν, density, yield stress, hardening, σ_R and friction angle;
    Particles built from them (as `from_gaussians` does) carry α = dp_alpha(φ) of each particle's own angle."""
    from fracture_gs.config import MaterialConfig, MaterialMapEntry
    from fracture_gs.sim.particles import material_arrays
    from fracture_gs.sim.physics.constitutive import MATERIAL_IDS, dp_alpha

    default = MaterialConfig(
        model="drucker_prager", E=3e5, nu=0.2, density=500.0, yield_stress=2e3, hardening=0.5,
        friction_angle=40.0, sigma_R=7e3,
    )  # fmt: skip
    entry = MaterialMapEntry(
        label=3, model="stvk_hencky_vm", E=4e4, nu=0.35, density=900.0, yield_stress=8e2, hardening=1.5,
        friction_angle=12.0, sigma_R=1e3,
    )  # fmt: skip
    labels = torch.tensor([0, 3, 0, 3])
    out = material_arrays(default, [entry], labels, 4)
    for key in ("E", "nu", "density", "yield_stress", "hardening", "sigma_R", "friction_angle"):
        want = torch.tensor([getattr(default, key), getattr(entry, key)] * 2, dtype=torch.float32)
        assert torch.equal(out[key], want), key
    ids = [MATERIAL_IDS["drucker_prager"], MATERIAL_IDS["stvk_hencky_vm"]] * 2
    assert out["material"].tolist() == ids
    p = S.Particles(x=torch.rand(4, 3), mass=out.pop("density"), volume=1.0, **out)
    want = dp_alpha(torch.tensor([40.0, 12.0] * 2))
    assert torch.allclose(p.alpha, want, rtol=1e-6, atol=0.0)
