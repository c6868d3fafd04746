"""Hand-written bug campaign, round three: the simulator's latch and its frame bookkeeping (`sim.simulator`,
`sim.frames`), each rule against a hand computation.

- A latched topology's fragment ids lie in [0, sim.max_fragments): every id of that range is accepted, and the
  first id past either end is refused with a sentence naming `sim.max_fragments` (the grid buffers, boxes and
  per-fragment tables are sized by it, so an id equal to it would write past them).
"""

import pytest
import torch
from simutil import block, config, particles

from fracture_gs import sim as S
from fracture_gs.errors import SimulationError
from fracture_gs.sim.topology import Topology


def _sim(max_fragments):
    x, vol = block((0.4, 0.4, 0.4), (0.5, 0.5, 0.5), 1 / 64)
    cfg = config(32, variant="full", max_fragments=max_fragments)
    return S.Simulator(cfg, particles(x, vol, rho=800.0, E=2e5, nu=0.25), device="cpu")


def _topology(n, top):
    """Fragment ids 0 … top spread over n particles (id `top` on the last one)."""
    fragment = (torch.arange(n) % top).to(torch.int32)
    fragment[-1] = top
    return Topology(
        fragment=fragment, band=torch.zeros(n, dtype=torch.int32), normal=(1.0, 0.0, 0.0), point=(0.45,) * 3
    )


@pytest.mark.parametrize("max_fragments", [2, 5])
def test_a_latch_takes_every_id_below_max_fragments_and_refuses_max_fragments_and_negative_ids(max_fragments):
    """With sim.max_fragments = K, ids 0 … K − 1 latch (n_fragments = K); a topology holding id K, or id −1,
    is refused with a SimulationError naming sim.max_fragments, and leaves the particles' labels unchanged."""
    sim = _sim(max_fragments)
    n = len(sim.particles)
    sim.latch(_topology(n, max_fragments - 1))
    assert sim.n_fragments == max_fragments
    assert int(sim.particles.fragment.max()) == max_fragments - 1
    before = sim.particles.fragment.clone()
    with pytest.raises(SimulationError, match="max_fragments"):
        sim.latch(_topology(n, max_fragments))
    bad = _topology(n, max_fragments - 1)
    bad.fragment[0] = -1
    with pytest.raises(SimulationError, match="max_fragments"):
        sim.latch(bad)
    assert torch.equal(sim.particles.fragment, before)
