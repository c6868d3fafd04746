"""Hand-written bug campaign, simulator and clock (`sim.simulator`, `sim.frames`, `sim.clock`): rules the earlier
tests left open, each against a hand computation.

- The active box covers where a particle at rest can fall in the next `horizon` seconds: d = ½|g|h² below the
  lowest particle, plus its stencil (base node ⌊(z − d − o)/Δx − ½⌋). A box fitted without the gravity term
  would start the frame with every falling particle's stencil leaving it (and redo the frame).
- G2P's clamp is symmetric: w − 1 free cells inside the first node and inside the last (w = wall_cells), so a
  body thrown at the lower walls stops as far from the grid's edge as one thrown at the upper walls.
"""

import math

from simutil import block, config, particles

from fracture_gs import sim as S

G = 9.8


def _resting_block(n=32):
    x, vol = block((0.4, 0.4, 0.5), (0.6, 0.6, 0.6), 1.0 / 64)
    cfg = config(n, gravity=(0.0, 0.0, -G), wall_cells=2)
    return S.Simulator(cfg, particles(x, vol), device="cpu"), x


def test_the_active_box_reaches_as_far_down_as_a_particle_at_rest_falls():
    """Particles at rest, horizon h with ½ g h² = 4Δx: the box's lowest z node is at or below the stencil base of
    the lowest particle moved down by 4Δx, ⌊(z_min − 4Δx)/Δx − ½⌋ (Δx = 1/32, origin 0)."""
    sim, x = _resting_block()
    dx = sim.grid.dx
    h = math.sqrt(2 * 4 * dx / G)  # ½ g h² = 4Δx
    sim.fit_active_box(h)
    zmin = float(x[:, 2].min())
    need = math.floor((zmin - 4 * dx) / dx - 0.5)
    lo_z = sim.slots.box[2]
    assert lo_z <= need, f"box starts at z node {lo_z}, a falling particle's stencil reaches {need}"


def test_g2p_clamps_particles_as_far_from_the_lower_walls_as_from_the_upper():
    """G2P clamps positions into [o + (w − 1)Δx, o + (s − w)Δx] per axis (w = wall_cells, s nodes): the first and
    the last node are (s − 1)Δx apart, so the clamp keeps the same w − 1 cells free on both sides. 32 nodes at
    Δx = 1/32 from o = 0, w = 2: [1/32, 30/32]."""
    sim, _ = _resting_block()
    lower, upper = [float(a) for a in sim.lower], [float(a) for a in sim.upper]
    assert lower == [1 / 32] * 3
    assert upper == [30 / 32] * 3
    top = 31 / 32  # the last node
    assert [top - u for u in upper] == lower
