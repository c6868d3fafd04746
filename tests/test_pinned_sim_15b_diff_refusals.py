"""What the differentiable solver (`sim.diff.solver.DiffSimulator`) refuses at construction, each with one sentence
naming the setting, and where it puts the domain walls.

- `sim.variant = "global_fragment_pass"` (a per-fragment pass, not a tape): refused; `local_multifield` and `full` are
  built.
- Materials: ids 0 (fixed-corotated) and 1 (neo-Hookean), by name or per particle, are built; von Mises (2) or
  Drucker–Prager (3) anywhere is refused, naming the differentiable ones.
- Timed particle regions are refused; planes, cuboids and spheres up to `MAX_BOUNDARIES` of each kind are built, one
  more of a kind is refused naming that kind.
- Domain walls: the particle clamp box runs from origin + (w − 1)·Δx to origin + (s − w)·Δx per axis (w =
  `wall_cells`, s nodes): (w − 1)·Δx in from the first and from the last node alike."""

import pytest
import torch
from simutil import config

from fracture_gs.config import CuboidBoundary, ParticleRegion, PlaneBoundary, SphereBoundary
from fracture_gs.errors import SimulationError
from fracture_gs.sim.diff.kernels import MAX_BOUNDARIES
from fracture_gs.sim.diff.solver import DiffSimulator

X = torch.tensor([[0.4, 0.4, 0.4], [0.6, 0.5, 0.45], [0.5, 0.6, 0.55]])


def _build(material="fixed_corotated", **kw):
    return DiffSimulator(config(32, **kw), X, "cpu", material=material)


def test_only_tape_variants_are_differentiable():
    """global_fragment_pass is refused with a message naming it and the variants that work; the others build."""
    with pytest.raises(SimulationError, match="global_fragment_pass.*local_multifield or full"):
        _build(variant="global_fragment_pass")
    for variant in ("baseline", "local_multifield", "full"):
        assert _build(variant=variant).spec.multifield == (variant != "baseline")


def test_only_the_hyperelastic_models_are_differentiable():
    """Material ids 0 and 1 (by name, or mixed per particle) build with those ids; a single von Mises (2) or
    Drucker–Prager (3) particle is refused, the message naming fixed_corotated and neo_hookean."""
    assert _build("neo_hookean").material.tolist() == [1, 1, 1]
    assert _build(torch.tensor([0, 1, 0])).material.tolist() == [0, 1, 0]
    for bad in ([0, 2, 0], [3, 0, 1], "stvk_hencky_vm", "drucker_prager"):
        with pytest.raises(SimulationError, match="fixed_corotated, neo_hookean are differentiable"):
            _build(torch.tensor(bad) if isinstance(bad, list) else bad)


def test_timed_particle_regions_are_refused():
    """A `type = "region"` boundary (an impulse on the particles) is refused, naming it."""
    region = ParticleRegion(lower=(0.3, 0.3, 0.3), upper=(0.7, 0.7, 0.7), delta_v=(1.0, 0.0, 0.0), end=0.01)
    with pytest.raises(SimulationError, match='type = "region"'):
        _build(boundaries=[region])


@pytest.mark.parametrize(
    "kind, make",
    [
        ("plane", lambda i: PlaneBoundary(point=(0.0, 0.0, 0.1 + 0.01 * i))),
        ("cuboid", lambda i: CuboidBoundary(lower=(0.1, 0.1, 0.1), upper=(0.2, 0.2, 0.2 + 0.01 * i))),
        ("sphere", lambda i: SphereBoundary(center=(0.1, 0.1, 0.1 + 0.01 * i), radius=0.05)),
    ],
)
def test_up_to_max_boundaries_of_each_kind_are_built_and_one_more_is_refused(kind, make):
    """MAX_BOUNDARIES (4) of a kind build (the kernels unroll that many); MAX_BOUNDARIES + 1 are refused with a
    message naming the kind and the count."""
    assert MAX_BOUNDARIES == 4
    _build(boundaries=[make(i) for i in range(MAX_BOUNDARIES)])
    with pytest.raises(SimulationError, match=f'at most 4 of type = "{kind}" \\(got 5\\)'):
        _build(boundaries=[make(i) for i in range(MAX_BOUNDARIES + 1)])


@pytest.mark.parametrize("walls", [1, 3, 5])
def test_the_domain_walls_are_equally_thick_on_both_sides(walls):
    """32 nodes of Δx = 1/32 m from the origin 0: the clamp box is [(w − 1)/32, (32 − w)/32] on every axis, so the
    lower wall sits (w − 1)·Δx above node 0 and the upper one (w − 1)·Δx below node 31."""
    sim = _build(wall_cells=walls)
    lo, hi = list(sim._lower), list(sim._upper)
    assert lo == [pytest.approx((walls - 1) / 32, abs=1e-7)] * 3
    assert hi == [pytest.approx((32 - walls) / 32, abs=1e-7)] * 3
    assert [31 / 32 - h for h in hi] == pytest.approx(lo, abs=1e-7)
