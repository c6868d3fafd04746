"""`sweep.expansion.scene_cost`, a scene cell's estimated seconds: frames × substeps per frame × 0.35 ms × (1 +
particles / 200k) + 10 ms per frame, where the substeps per frame are frame_dt / Δt (at least 1) and, with
`sim.adaptive_dt`, Δt = min(sim.dt, cfl·Δx / c) with c the P-wave speed √((λ + 2μ)/ρ). Worked here with ν = 0, so
c = √(E/ρ) exactly, over wave speeds from 0 (E = 0) and 0.05 m/s (a jelly, slower than 1 m/s) to 40 m/s."""

from __future__ import annotations

import pytest

from fracture_gs.config import SceneConfig
from fracture_gs.sweep.expansion import scene_cost

RHO, DX, CFL, FRAME_DT = 100.0, 0.02, 0.4, 0.01


def scene(c: float, dt: float, adaptive: bool = True, frames: int = 8, particles=1000) -> SceneConfig:
    """A cell whose material has P-wave speed c (ν = 0: E = ρ c²)."""
    cfg = SceneConfig()
    cfg.material.E, cfg.material.nu, cfg.material.density = RHO * c * c, 0.0, RHO
    cfg.sim.adaptive_dt, cfg.sim.dt, cfg.sim.dx, cfg.sim.cfl = adaptive, dt, DX, CFL
    cfg.frames, cfg.frame_dt, cfg.particles = frames, FRAME_DT, particles
    return cfg


def by_hand(substeps_per_frame: float, frames: int = 8, particles: float = 1000) -> float:
    return 0.35e-3 * frames * substeps_per_frame * (1 + particles / 2e5) + 0.01 * frames


@pytest.mark.parametrize(
    "c, dt, per_frame",
    [
        (0.0, 0.01, 1.0),  # no wave at all: the CFL step is unbounded, sim.dt = frame_dt gives one substep
        (0.05, 0.01, 1.0),  # CFL step 0.16 s > sim.dt
        (0.5, 0.01, 1.0),  # CFL step 16 ms > sim.dt = 10 ms: still one substep, a slow wave never adds any
        (0.5, 2.5e-3, 4.0),  # sim.dt binds
        (4.0, 0.01, 5.0),  # CFL step 2 ms binds: 5 substeps
        (40.0, 0.01, 50.0),  # CFL step 0.2 ms: 50 substeps
    ],
)
def test_adaptive_estimate_takes_the_smaller_of_sim_dt_and_the_cfl_step(c, dt, per_frame):
    """With adaptive Δt the substeps per frame are frame_dt / min(sim.dt, cfl·Δx/c), however slow the wave (a
    material slower than 1 m/s is bound by sim.dt, not by a floor on c)."""
    if c > 0:
        assert per_frame == pytest.approx(FRAME_DT / min(dt, CFL * DX / c))
    assert scene_cost(scene(c, dt)) == pytest.approx(by_hand(per_frame), rel=1e-12)


def test_fixed_step_ignores_the_material_and_a_long_step_is_one_substep():
    """Without adaptive Δt the material does not matter: frame_dt / sim.dt substeps (2.5 ms: 4), and a sim.dt
    longer than the frame still costs one substep a frame, a zero one is floored at 1 ps; no particle count means
    20,000 particles."""
    for c in (0.05, 4.0, 400.0):
        assert scene_cost(scene(c, 2.5e-3, adaptive=False)) == pytest.approx(by_hand(4.0), rel=1e-12)
    assert scene_cost(scene(4.0, 0.05, adaptive=False)) == pytest.approx(by_hand(1.0), rel=1e-12)
    assert scene_cost(scene(4.0, 2.5e-3, adaptive=False, particles=None)) == pytest.approx(
        by_hand(4.0, particles=20_000), rel=1e-12
    )
    # a zero step is floored at 1 ps (10¹⁰ substeps a frame), not a division by zero
    assert scene_cost(scene(4.0, 0.0, adaptive=False)) == pytest.approx(by_hand(1e10), rel=1e-12)
