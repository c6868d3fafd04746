"""`sim.particle_order = "cell"`: the scene's Gaussians sorted once by grid cell before a run, so that a GPU's P2G
sums each thread's run of particles sharing a cell before its atomics. The run sees the same Gaussians, each kept
whole, in cell order, and moves them as the scene-order run does up to the order of floating-point sums."""

import dataclasses

import pytest
import torch

from fracture_gs.io.config import load_config
from fracture_gs.pipeline import make_simulator, prepare_scene
from fracture_gs.sim import Particles, SimulationError, Simulator
from fracture_gs.sim.grid.domain import fit_grid
from fracture_gs.sim.neighbourhood import cell_order
from fracture_gs.sim.options import P2G_RUN


def bread(order: str, n: int = 1500):
    cfg = load_config("bread")
    cfg.particles, cfg.sim.particle_order = n, order
    return cfg


def scene_to_cell(cfg, means):  # [N, 3] scene-order means -> the permutation cell order applies
    origin, dx, shape = fit_grid(cfg.sim, means.float())
    return cell_order(means.float(), origin, dx, shape, "cell")


def test_cell_order_is_the_scene_permuted_with_each_gaussian_whole():
    a = prepare_scene(bread("scene")).gaussians
    b = prepare_scene(bread("cell")).gaussians
    order = scene_to_cell(bread("cell"), a.means)
    assert not torch.equal(order, torch.arange(len(order))), "the bread does not come in cell order already"
    for f in dataclasses.fields(a):
        va, vb = getattr(a, f.name), getattr(b, f.name)
        if torch.is_tensor(va):
            assert torch.equal(vb, va[order]), f.name
        elif f.name == "extra":
            assert va.keys() == vb.keys() and all(torch.equal(vb[k], va[k][order]) for k in va)
    origin, dx, shape = fit_grid(bread("cell").sim, b.means.float())
    base = torch.floor((b.means.float() - torch.tensor(origin)) / dx - 0.5).long()
    key = (base[:, 0] * shape[1] + base[:, 1]) * shape[2] + base[:, 2]
    assert bool((key[1:] >= key[:-1]).all()), "consecutive particles' stencil base cells never decrease"


@pytest.mark.slow
def test_a_run_in_cell_order_moves_like_the_scene_order_run(device):
    x, x0 = {}, {}
    for order in ("scene", "cell"):
        cfg = bread(order)
        gs = prepare_scene(cfg, device).gaussians
        sim = make_simulator(cfg, gs, "baseline", device)
        runs = P2G_RUN if order == "cell" and device != "cpu" else 0
        assert sim.options.p2g_run == runs, "runs on a GPU in cell order"
        x0[order] = sim.particles.x.clone()
        for _ in range(3):
            sim.advance(cfg.frame_dt)
        x[order] = sim.particles.x
    order = scene_to_cell(bread("cell"), x0["scene"])
    torch.testing.assert_close(x0["scene"][order], x0["cell"], rtol=0, atol=0)
    extent = float((x0["scene"].max(0).values - x0["scene"].min(0).values).max())
    moved = float((x["scene"] - x0["scene"]).norm(dim=1).max())
    assert moved > 1e-4 * extent, "the pulled ends moved"
    assert float((x["scene"][order] - x["cell"]).norm(dim=1).max()) <= 1e-5 * extent


def test_an_unknown_particle_order_is_one_sentence():
    P = Particles.from_gaussians(prepare_scene(bread("scene")).gaussians, bread("scene"))
    with pytest.raises(SimulationError, match="sim.particle_order 'random' is unknown; use scene or cell"):
        Simulator(bread("random").sim, P)
