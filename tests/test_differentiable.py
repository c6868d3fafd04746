"""Gradients through the simulation (issue 15): the Warp adjoints of `DiffSimulator` frames against
central finite differences of the float64 torch twin, for `baseline` and for `full` on both sides of
a latch with contact and friction active; finite gradients on hard cases."""

import pytest
import torch
from simutil import block, config

from fracture_gs import sim as S
from fracture_gs.sim.diff import DiffSimulator
from fracture_gs.sim.diff import reference as DR

NU = 0.3
RHO = 1000.0


def scene(variant, latch_frame=None, friction=0.0, seed=0, gravity=(0.0, 0.0, -9.8)):
    """Two blocks' worth of particles split at x = 0.45; with a latch the halves are pushed together
    (contact fires after it) and slide (friction acts)."""
    g = torch.Generator().manual_seed(seed)
    x, vol = block((0.35, 0.35, 0.35), (0.55, 0.5, 0.5), 1 / 32)
    n = len(x)
    cfg = config(16, variant=variant, dt=2e-3, gravity=gravity, contact=S.ContactConfig(friction=friction))
    topo = None
    if latch_frame is not None:
        topo = S.Topology.from_plane(x, (0.45, 0.5, 0.5), (1.0, 0.0, 0.0), 1 / 16, latch_frame=latch_frame)
    sim = DiffSimulator(cfg, x, topologies=[topo] if topo is not None else [])
    side = torch.where(x[:, 0] < 0.45, 1.0, -1.0).double()
    v0 = 0.3 * torch.randn(n, 3, generator=g, dtype=torch.float64)
    v0[:, 0] += 0.4 * side  # the halves approach each other
    v0[:, 1] += 0.2 * side  # and slide along the interface
    return sim, x.double(), v0, vol


def loss_of(sim, x0, v0, E, vol, frames=3, ref=False, F0=None):
    n = x0.shape[0]
    mu, lam = E / (2 * (1 + NU)), E * NU / ((1 + NU) * (1 - 2 * NU))
    mass = torch.full((n,), RHO * vol, dtype=torch.float64)
    V = torch.full((n,), vol, dtype=torch.float64)
    C = torch.zeros(n, 3, 3, dtype=torch.float64)
    F = torch.eye(3, dtype=torch.float64).expand(n, 3, 3).contiguous() if F0 is None else F0
    x, v = x0, v0
    for f in range(frames):
        if ref:
            x, v, C, F = DR.frame(sim, sim.plans[f], x, v, C, F, mu, lam, mass, V)
        else:
            x, v, C, F = sim.step(0.01, x, v, C, F, mu, lam, mass, V)
    w = torch.linspace(0.5, 1.5, n, dtype=torch.float64)
    return (w[:, None] * x**2).sum() + 0.1 * (F**2).sum() + (w[:, None] * v).sum()


def check(sim, x0, v0, vol, E0=1e3, frames=3):
    """Relative error of d L/d E (global), d L/d v0, d L/d x0 (random directions) against central
    differences of the float64 twin, run on the same frame plans (substeps, routing)."""
    n = x0.shape[0]
    E = torch.full((n,), E0, dtype=torch.float64, requires_grad=True)
    v0 = v0.clone().requires_grad_()
    x0 = x0.clone().requires_grad_()
    loss_of(sim, x0, v0, E, vol, frames).backward()
    g = torch.Generator().manual_seed(1)
    d = torch.randn(n, 3, generator=g, dtype=torch.float64)
    out = {}
    with torch.no_grad():

        def L(xx, vv, EE):
            return float(loss_of(sim, xx, vv, EE, vol, frames, ref=True))

        h = 1e-3 * E0
        fd = (L(x0, v0, E + h) - L(x0, v0, E - h)) / (2 * h)
        out["E"] = (float(E.grad.sum()), fd)
        h = 1e-6
        out["v0"] = (float((v0.grad * d).sum()), (L(x0, v0 + h * d, E) - L(x0, v0 - h * d, E)) / (2 * h))
        out["x0"] = (float((x0.grad * d).sum()), (L(x0 + h * d, v0, E) - L(x0 - h * d, v0, E)) / (2 * h))
    for k, (adj, fd) in out.items():
        assert abs(adj - fd) <= 1e-3 * abs(fd), f"d L/d {k}: adjoint {adj}, central difference {fd}"
    return out


@pytest.mark.slow
def test_gradients_match_finite_differences_baseline():
    """Shared field, no fracture: E, v0, x0 gradients within 1e-3 of float64 central differences."""
    sim, x, v0, vol = scene("baseline")
    check(sim, x, v0, vol)


@pytest.mark.slow
@pytest.mark.parametrize("friction", [0.0, 0.4])
def test_gradients_match_finite_differences_across_a_latch(friction):
    """FractureFields latching after frame 1 (topology held fixed, the halves pushed together so the
    contact projection fires, with and without Coulomb friction): gradients before and after the
    latch within 1e-3 of float64 central differences."""
    sim, x, v0, vol = scene("full", latch_frame=1, friction=friction)
    check(sim, x, v0, vol, frames=3)
    assert sim.plans[0].fields == 1 and sim.plans[2].fields == 2, "one frame before the latch, then two fields"


def test_no_nan_gradients_on_hard_cases():
    """Near-inverted F (det 1e-3, and one slightly inverted particle) and a stiff material at its CFL
    bound: every gradient finite."""
    sim, x, v0, vol = scene("full", latch_frame=0)
    n = x.shape[0]
    F0 = torch.eye(3, dtype=torch.float64).expand(n, 3, 3).clone()
    F0[: n // 3, 2, 2] = 1e-3
    F0[0, 2, 2] = -1e-3
    E = torch.full((n,), 1e3, dtype=torch.float64, requires_grad=True)
    v = v0.clone().requires_grad_()
    loss_of(sim, x, v, E, vol, frames=2, F0=F0).backward()
    assert torch.isfinite(E.grad).all() and torch.isfinite(v.grad).all()
    stiff = DiffSimulator(config(16, variant="baseline", dt=1e-3, adaptive_dt=True, cfl=0.4), x.float())
    stiff.wave_speed = float((1e7 * (1 - NU) / ((1 + NU) * (1 - 2 * NU)) / RHO) ** 0.5)
    E = torch.full((n,), 1e7, dtype=torch.float64, requires_grad=True)
    v = v0.clone().requires_grad_()
    loss_of(stiff, x, v, E, vol, frames=1).backward()
    assert stiff.plans[0].n > 1 and torch.isfinite(E.grad).all() and torch.isfinite(v.grad).all()


@pytest.mark.slow
def test_fit_material_example_recovers_E(tmp_path):
    """examples/fit_material.py (the CPU run, small sagging beam): from E = 5e3 Pa, gradient descent through
    the simulation and the torch rasterizer on an image loss recovers E = 2e4 Pa within 5 %, and writes
    its loss curve, side-by-side figure and summary."""
    import json
    import subprocess
    import sys
    from pathlib import Path

    script = Path(__file__).resolve().parent.parent / "examples" / "fit_material.py"
    r = subprocess.run(
        [sys.executable, str(script), "--out", str(tmp_path)], capture_output=True, text=True, timeout=600
    )
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]
    fit = json.loads((tmp_path / "fit.json").read_text())
    assert fit["relative_error"] <= 0.05 and fit["E_start"] == 5e3 and fit["E_true"] == 2e4
    assert (tmp_path / "loss.png").stat().st_size > 0 and (tmp_path / "side_by_side.png").stat().st_size > 0
