"""The slot storage's buffer for the pool rows' slot-0 mass gradients (`SlotStorage.pool_gradient_buffer`) has one
vec3 per pool row: it is allocated once and handed out unchanged (the same array, so a recorded graph keeps
pointing at it) while the pool keeps its capacity, and reallocated to the new capacity when the pool grows —
a kernel over the new rows must never index past its end."""

import torch
from simutil import block, particles

from fracture_gs import sim as S


def _sim():
    x, vol = block((0.3, 0.4, 0.4), (0.7, 0.6, 0.6), 0.05)
    cfg = S.SimConfig(
        dx=1 / 8,
        grid_shape=(8, 8, 8),
        gravity=(0, 0, 0),
        variant="full",
        wall_cells=0,
        field_slots=4,
        contact=S.ContactConfig(friction=0.0, normal="mass_gradient"),
        grid_storage="slots",
    )
    return S.Simulator(cfg, particles(x, vol), device="cpu")


def test_the_gradient_buffer_follows_the_pool_capacity_and_is_kept_while_it_holds():
    """Two calls at one capacity give the same array; after the pool grows 4×, the buffer has the new capacity's
    rows (zeroed), and is then kept again."""
    sim = _sim()
    g = sim.grid
    first = sim.slots.pool_gradient_buffer()
    cap = g.capacity
    assert tuple(sim.slots.grad0.shape) == (cap, 3) and first.shape == (cap,)
    sim.slots.grad0.fill_(5.0)
    again = sim.slots.pool_gradient_buffer()
    assert again is first and float(sim.slots.grad0.min()) == 5.0, "kept, not reallocated"
    assert g.ensure_pool(4 * cap)
    assert g.capacity == 8 * cap
    grown = sim.slots.pool_gradient_buffer()
    assert grown.shape == (8 * cap,) and tuple(sim.slots.grad0.shape) == (8 * cap, 3)
    assert torch.equal(sim.slots.grad0, torch.zeros(8 * cap, 3))
    assert sim.slots.pool_gradient_buffer() is grown
