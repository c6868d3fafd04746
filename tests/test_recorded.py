"""Recorded per-frame queries (`sim/recorded.py`): on CUDA a replay reads the buffers as they are now, so
it answers exactly as running the query again; a new key records anew; only the newest `keep` stay. On
the CPU the query simply runs. The solver's solo flags come out the same either way."""

import math

import pytest
import torch

from fracture_gs.sim.recorded import Recorded


def test_a_recorded_query_answers_as_running_it_again(device):
    x = torch.rand(1000, 3, device=device)
    rec = Recorded(device, keep=2)

    def query(k):
        return lambda: (x * k).sum(0).double() + torch.cos(x).amax(0)

    for _ in range(3):
        x.add_(0.1)  # the state moves in place between frames, as the solver's does
        for k in (1, 2, 3):
            assert torch.equal(rec(k, query(k)), query(k)())
    assert len(rec.graphs) == (2 if rec.records else 0)


@pytest.mark.slow
def test_solo_flags_from_the_recorded_mask_equal_the_mask(device):
    """Each frame's solo flags (recorded on CUDA, one graph per neighbourhood radius) equal `solo_mask`
    run on that frame's state."""
    from fracture_gs.io.config import load_config
    from fracture_gs.pipeline import load_scene, make_simulator
    from fracture_gs.sim.neighbourhood import solo_mask

    cfg = load_config("plate_drop")
    cfg.particles = 3000
    sim = make_simulator(cfg, load_scene(cfg, device), "full", device)
    checked = 0
    for _ in range(30):
        sim.advance(cfg.frame_dt)
        if not sim.multifield:
            continue
        P, g = sim.particles, sim.grid
        gravity = math.hypot(*sim.cfg.gravity)
        travel = sim.fit_active_box(cfg.frame_dt) * cfg.frame_dt + 0.5 * gravity * cfg.frame_dt**2
        reach = 4.0 * g.dx + 2.0 * travel + sim.runner.box_slack * g.dx
        want = solo_mask(P.x, P.fragment, g.origin, g.dx, g.shape, reach)
        if want is not None:
            assert torch.equal(sim.slots.solo, want)
            checked += 1
    assert checked >= 10
    if device.startswith("cuda"):
        assert sim.slots.queries.graphs
