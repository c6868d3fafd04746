"""Property: a small simulation state with extreme but finite parameters either advances two frames to a
finite state (x, v, C, F all finite: never NaN in an output) or stops with one of our exceptions —
`SimulationError` (an impossible request, e.g. more substeps than allowed) or `SimulationDiverged` (the
state blew up, with the frame and cause) — never another exception and never a silent NaN. States: 1–60
particles anywhere in a 16³ grid, E from 1e-2 to 1e9 Pa, ν in [0, 0.49], density from 1e-2 to 1e5
kg/m³, speeds up to 50 m/s, gravity up to 100 m/s², F stretched or compressed up to 10×, every material
model and variant, optional fracture strength with the stress provider."""

from __future__ import annotations

import pytest
import torch
from fuzzutil import Tally, fuzz_settings
from hypothesis import given
from hypothesis import strategies as st

from fracture_gs import sim as S
from fracture_gs.config import MATERIALS, TopologyConfig
from fracture_gs.errors import SimulationDiverged, SimulationError
from fracture_gs.variants import VARIANT_NAMES

N_GRID = 16


def log_uniform(lo: float, hi: float):
    return st.floats(0.0, 1.0).map(lambda u: lo * (hi / lo) ** u)


@st.composite
def state(draw):
    n = draw(st.integers(1, 60))
    g = torch.Generator().manual_seed(draw(st.integers(0, 2**31 - 1)))
    spread = draw(st.sampled_from([0.02, 0.1, 0.4]))
    x = 0.5 + spread * (torch.rand(n, 3, generator=g) - 0.5)
    speed = draw(st.sampled_from([0.0, 0.5, 5.0, 50.0]))
    v = speed * (torch.rand(n, 3, generator=g) - 0.5)
    stretch = draw(st.sampled_from([1.0, 0.1, 0.5, 2.0, 10.0]))
    F = torch.eye(3).repeat(n, 1, 1) * torch.tensor([stretch, 1.0, 1.0])[:, None]
    rho, vol = draw(log_uniform(1e-2, 1e5)), (1.0 / N_GRID / 2) ** 3
    P = S.Particles(
        x=x,
        v=v,
        F=F,
        mass=torch.full((n,), rho * vol),
        volume=torch.full((n,), vol),
        E=draw(log_uniform(1e-2, 1e9)),
        nu=draw(st.floats(0.0, 0.49)),
        material=draw(st.sampled_from(MATERIALS)),
        yield_stress=draw(log_uniform(1e-2, 1e6)),
        friction_angle=draw(st.floats(0.0, 60.0)),
        sigma_R=draw(st.sampled_from([float("inf"), 1.0, 1e3])),
    )
    variant = draw(st.sampled_from(VARIANT_NAMES))
    cfg = S.SimConfig(
        dx=1.0 / N_GRID,
        grid_shape=(N_GRID,) * 3,
        grid_origin=(0.0, 0.0, 0.0),
        gravity=(0.0, 0.0, -draw(st.sampled_from([0.0, 9.8, 100.0]))),
        variant=variant,
        adaptive_dt=True,
        cfl=draw(st.sampled_from([0.1, 0.5, 0.9])),
        dt=2e-3,
        max_substeps_per_frame=200,
    )
    stress = variant != "baseline" and draw(st.booleans())
    return P, cfg, stress


@pytest.mark.slow
@pytest.mark.usefixtures("one_thread")
def test_fuzz_sim(capsys):
    tally = Tally("simulation")

    @fuzz_settings(400)
    @given(state())
    def prop(case):
        P, cfg, stress = case
        category = f"{cfg.variant}{' + stress provider' if stress else ''}"
        try:
            provider = (
                S.StressProvider(TopologyConfig(provider="stress", min_particles=1, persist_frames=1))
                if stress
                else None
            )
            sim = S.Simulator(cfg, P, device="cpu", provider=provider)
            for _ in range(2):
                sim.advance(0.01)
        except (SimulationError, SimulationDiverged) as err:
            assert str(err).strip(), "an error without a message"
            tally.add(category, "our error")
            return
        except Exception:
            tally.add(category, "traceback")
            raise
        p = sim.particles
        finite = all(bool(torch.isfinite(t).all()) for t in (p.x, p.v, p.C, p.F))
        if not finite:
            tally.add(category, "silent acceptance")
            raise AssertionError("the state became non-finite without SimulationDiverged")
        tally.add(category, "clean load")

    prop()
    tally.report(capsys)
    assert tally.total() >= 400 and tally.total("traceback") == 0 and tally.total("silent acceptance") == 0
    assert tally.total("clean load") > 40 and tally.total("our error") > 10
