"""The capture's substep note states the CFL step in milliseconds, the P-wave speed in m/s and Δx in mm, each
worked out by hand for the material and grid (`capture.materials.substep_note`)."""

from __future__ import annotations

import pytest

from fracture_gs.capture.materials import substep_note
from fracture_gs.config import SceneConfig


@pytest.mark.parametrize(
    "dx, text",
    [
        (0.01, "Δt ≤ 0.258 ms from the CFL bound (wave speed 15.5 m/s at Δx = 10 mm): about 39 substeps a frame"),
        (0.025, "Δt ≤ 0.645 ms from the CFL bound (wave speed 15.5 m/s at Δx = 25 mm): about 16 substeps a frame"),
    ],
)
def test_substep_note_reads_milliseconds_and_millimetres(dx, text):
    """E = 400 kPa, ν = 0.25, ρ = 2000 kg/m³: c = √(E(1−ν)/(ρ(1+ν)(1−2ν))) = √240 = 15.49 m/s; with CFL 0.4 the
    step is 0.4·Δx/c, 0.258 ms at Δx = 10 mm and 0.645 ms at 25 mm (seconds × 1000, three digits), and a 10 ms
    frame takes ⌈10/0.2582⌉ = 39 and ⌈10/0.6455⌉ = 16 substeps (sim.dt = 1 ms is the larger step)."""
    cfg = SceneConfig()
    cfg.material.E, cfg.material.nu, cfg.material.density = 4.0e5, 0.25, 2000.0
    cfg.sim.cfl, cfg.sim.dx, cfg.sim.dt, cfg.frame_dt = 0.4, dx, 1e-3, 0.01
    assert substep_note(cfg) == text
