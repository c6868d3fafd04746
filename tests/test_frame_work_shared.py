"""Work a CPU frame did twice, now done once, with the same numbers to the last bit (issue 36, item 5):

- the diagnostics' float64 polar rotation of F (fixed-corotated energy) is the frame's SH rotation, rounded once;
- the next substep takes the stress the diagnostics' shadow transfer computed of the same state;
- the viewer record's float16 cast on the CPU is numpy's single rounding;
- the painter's SH colours are computed for the drawn Gaussians only;
- the surface measure asks for det F only when some particle is near another piece.

Each test compares against the work done the old way and fails if the shortcut changes a bit or uses stale data.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch

from fracture_gs.linalg import polar_rotation


def _random_F(n: int, seed: int) -> torch.Tensor:  # [n, 3, 3] float32: mild, inverted and nearly flat ones
    g = torch.Generator().manual_seed(seed)
    F = torch.eye(3) + 0.3 * torch.randn(n, 3, 3, generator=g)
    F[: n // 8] *= -1.0  # det < 0: the SVD branch with its flipped axis
    F[n // 8 : n // 4, 2] *= 1e-4  # nearly flat: the SVD branch
    return F


def test_float32_polar_is_the_float64_polar_rounded_once():
    """`polar_rotation` of float32 F converts each F to float64 and rounds its R once, so it equals the float64
    rotation of the same F cast to float32 bit for bit, on every branch (Newton, inverted, nearly flat): the reason
    the frame may take the diagnostics' float64 R."""
    F = _random_F(4000, 0)
    assert torch.equal(polar_rotation(F), polar_rotation(F.double()).float())


def _bread(particles: int = 2000):
    """Bread at `particles` particles, cut by an oracle plane at frame 1 (so a few frames run latched)."""
    from fracture_gs.io.config import load_config

    cfg = load_config("bread")
    cfg.particles = particles
    cfg.topology.provider = "oracle"
    cfg.topology.point, cfg.topology.normal, cfg.topology.latch_frame = (0.5, 0.5, 0.24), (1.0, 0.0, 0.0), 1
    return cfg


@pytest.fixture(scope="module")
def small_bread():
    """(cfg, Gaussians) of `_bread` at 1,000 particles, built once for the tests that step it."""
    from fracture_gs.pipeline import load_scene

    cfg = _bread(1000)
    return cfg, load_scene(cfg, "cpu")


def _run(cfg, gs, frames: int, shared: bool, monkeypatch):
    """Metrics rows, each frame's SH rotations and the final state of `full`; `shared` False switches both
    shortcuts off (no rotation handed over, no stress kept), i.e. the work done twice as before."""
    from fracture_gs.pipeline import make_simulator, simulate
    from fracture_gs.sim.diagnostics.tracker import Diagnostics
    from fracture_gs.sim.simulator import Simulator

    with monkeypatch.context() as m:
        if not shared:
            m.setattr(Simulator, "can_keep_stress", lambda self: False)
            m.setattr(Diagnostics, "take_rotation", lambda self: None)
        sim = make_simulator(cfg, gs, "full", "cpu")
        rows, rotations, handed = [], [], []
        for out in simulate(sim, torch.zeros(1), frames, cfg.frame_dt):
            rows.append(json.dumps(out.metrics, sort_keys=True, default=str))
            handed.append(out.rotation64 is not None)
            rotations.append(out.rotations)
        P = sim.particles
        return rows, rotations, handed, [t.clone() for t in (P.x, P.v, P.F, P.C)], sim


@pytest.mark.slow
def test_shared_rotation_and_kept_stress_change_no_number(monkeypatch):
    """A latched fixed-corotated run on the CPU: every frame's SH rotation is the diagnostics' R (handed over) and
    equals `polar_rotation` of that frame's F; the shadow transfer's stress stands in for the next substep's
    (fewer stress launches); the metrics rows, the rotations and the final x, v, F, C equal the run that does the
    work twice, bit for bit."""
    import warp as wp

    from fracture_gs.pipeline import load_scene

    cfg = _bread()
    gs = load_scene(cfg, "cpu")
    launches = {"shared": 0, "twice": 0}
    launch = wp.launch

    def counting(kernel, *a, **k):
        if kernel.key == "compute_stress":
            launches[key] += 1
        return launch(kernel, *a, **k)

    monkeypatch.setattr(wp, "launch", counting)
    key = "shared"
    rows, rot, handed, state, sim = _run(cfg, gs, 4, True, monkeypatch)
    key = "twice"
    rows0, rot0, handed0, state0, _ = _run(cfg, gs, 4, False, monkeypatch)
    assert sim.latched and all(handed) and not any(handed0)
    assert launches["shared"] < launches["twice"], launches
    assert rows == rows0
    assert all(torch.equal(a, b) for a, b in zip(rot, rot0))
    assert all(torch.equal(a, b) for a, b in zip(state, state0))


def test_a_kept_stress_is_recomputed_once_the_state_changed(small_bread):
    """The stress kept for the next substep stands only for the state it was computed of: after an in-place write
    to F (a torch write bumps its version) the substep computes τ again, so one substep from the changed state
    equals that of a simulator that kept nothing (with a stale τ the velocities would differ)."""
    from fracture_gs.pipeline import make_simulator

    cfg, gs = small_bread
    ends = []
    for keep in (True, False):
        sim = make_simulator(cfg, gs, "full", "cpu")
        sim.advance(cfg.frame_dt)
        assert sim.can_keep_stress()
        sim.compute_stress(sim.stress, commit=False)
        if keep:
            sim.keep_stress()
        sim.particles.F.mul_(1.01)  # the state changes after τ was kept
        sim.substep()
        ends.append(sim.particles.v.clone())
    assert torch.equal(ends[0], ends[1])


def test_a_kept_stress_is_skipped_only_by_the_next_substep(small_bread):
    """`keep_stress` marks τ of the current state; the frame's first substep takes it (the mark is spent) and the
    others compute their own, although a frame counts its substeps only at its end: a frame after a mark equals a
    frame without one (a mark left standing would give every substep the first one's τ)."""
    from fracture_gs.pipeline import make_simulator

    cfg, gs = small_bread
    ends = []
    for keep in (True, False):
        sim = make_simulator(cfg, gs, "full", "cpu")
        sim.advance(cfg.frame_dt)
        sim.compute_stress(sim.stress, commit=False)
        if keep:
            sim.keep_stress()
        assert sim.advance(cfg.frame_dt) > 1
        assert sim._stress_of is None
        ends.append(torch.cat([sim.particles.v.flatten(), sim.particles.F.flatten()]))
    assert torch.equal(ends[0], ends[1])


def test_plastic_particles_never_keep_a_stress(small_bread):
    """A plastic model's substep writes its return into F (commit), which a stress computed with commit=False did
    not: with one von Mises particle the stress is never kept."""
    from fracture_gs.pipeline import make_simulator
    from fracture_gs.sim.physics.constitutive import MATERIAL_IDS

    cfg, gs = small_bread
    sim = make_simulator(cfg, gs, "full", "cpu")
    assert sim.can_keep_stress()
    sim.particles.material[0] = MATERIAL_IDS["stvk_hencky_vm"]
    assert not sim.can_keep_stress()


def test_cpu_float16_cast_rounds_once_like_half_exact():
    """The record's float16 cast on the CPU (numpy's) equals `half_exact` bit for bit, at ties, subnormals, the
    largest finite value and signed zero, where a cast through float32 would round twice."""
    from fracture_gs.viewer.encode_torch import _half, half_exact

    g = torch.Generator().manual_seed(3)
    scale = 10.0 ** torch.randint(-9, 5, (50000,), generator=g).double()
    x = (torch.randn(50000, generator=g, dtype=torch.float64) * scale).clamp(-65504.0, 65504.0)
    edge = [0.0, -0.0, 65504.0, -65504.0, 2.0**-25, 2.0**-24, 3 * 2.0**-26, 1 + 2.0**-11, 1 + 3 * 2.0**-11]
    edge += [2.0**-14 * (1 - 2.0**-11), 2.0**-14 + 2.0**-25, (1 + 2.0**-11) * (1 + 2.0**-30)]
    x = torch.cat([x, torch.tensor(edge, dtype=torch.float64)])
    assert torch.equal(_half(x).view(torch.int16), half_exact(x).view(torch.int16))
    assert not torch.equal(x.float().half().view(torch.int16), half_exact(x).view(torch.int16))


def test_sh_colours_of_a_subset_are_the_rows_of_all():
    """`sh_colors` is row-wise: the colours of the drawn Gaussians computed alone equal their rows of the colours of
    all, bit for bit (the painter computes only those)."""
    from fracture_gs.render.gaussians import sh_colors

    g = torch.Generator().manual_seed(4)
    n = 6000
    sh, means = torch.randn(n, 16, 3, generator=g), torch.rand(n, 3, generator=g)
    R = polar_rotation(_random_F(n, 5))
    cam = torch.tensor([0.5, -1.0, 0.4])
    full = sh_colors(sh, means, cam, R)
    for m in (1, 5, 17, 1500, 4269):
        keep = torch.randperm(n, generator=g)[:m].sort().values
        part = sh_colors(sh.index_select(0, keep), means.index_select(0, keep), cam, R.index_select(0, keep))
        assert torch.equal(part, full.index_select(0, keep)), m


def _blocks(gap: float) -> tuple[torch.Tensor, torch.Tensor]:
    """Two jittered 10³ blocks (spacing 0.02 m) `gap` apart along x (negative: pressed into each other)."""
    g = torch.Generator().manual_seed(6)
    parts, ids = [], []
    for k in range(2):
        a = torch.arange(10) * 0.02
        p = torch.stack(torch.meshgrid(a + k * (0.2 + gap), a, a, indexing="ij"), -1).reshape(-1, 3).double()
        parts.append(p + 0.004 * torch.rand(p.shape, generator=g, dtype=torch.float64))
        ids.append(torch.full((len(p),), k, dtype=torch.long))
    return torch.cat(parts), torch.cat(ids)


@pytest.mark.parametrize("gap, asked", [(0.5, False), (-0.04, True)])
def test_surface_measure_asks_for_det_f_only_when_pieces_are_near(gap, asked):
    """The volume ratio handed as a function gives the depths of the tensor itself, and is called only when some
    particle is near another piece: blocks far apart never ask, pressed blocks do (and read a depth)."""
    from fracture_gs.sim.diagnostics import penetration as pen

    x, frag = _blocks(gap)
    cal = pen.calibrate(x[frag == 0], frag[frag == 0])  # one block's scales, as at a latch
    cal["filled"] = cal["filled"].repeat(2)
    J = 1.0 + 0.01 * torch.rand(len(x), generator=torch.Generator().manual_seed(7), dtype=torch.float64)
    calls = []

    def ratio():
        calls.append(1)
        return J

    lazy = pen.surface_penetration(x, frag, 0.002, cal, ratio)
    eager = pen.surface_penetration(x, frag, 0.002, cal, J)
    assert lazy == eager and bool(calls) is asked
    assert (eager["depth"] > 0) is asked
    np.testing.assert_equal(len(calls), int(asked))


def test_inference_mode_particles_never_keep_a_stress(small_bread):
    """Tensors made in `torch.inference_mode` keep no version counter, so a change to them could not void a kept
    stress: particles with such an F never keep one (and checking costs no error)."""
    from fracture_gs.pipeline import make_simulator

    cfg, gs = small_bread
    sim = make_simulator(cfg, gs, "full", "cpu")
    assert sim.can_keep_stress()
    with torch.inference_mode():
        sim.particles.F = sim.particles.F.clone()
    assert not sim.can_keep_stress()
