"""`BoxStorage`: the per-fragment boxes (`fragment_boxes.FragmentBoxes`) as a `storage.Storage` of a simulator.

After a latch of a fragment-conditioned variant, with `sim.grid_storage = "boxes"` or `"auto"`, every fragment's
field lives in its own dense box (docs/DESIGN.md "Grid storage: per-fragment boxes"): refitted every frame to its
particles plus their travel and the slack (a particle whose stencil leaves its box is counted and the frame redone
with more slack: boxes never take the whole grid), emptied after each substep's G2P. The boxes hold the
fragment-conditioned variants only, which have no per-fragment pass (`only_fragment` is always −1).
"""

from __future__ import annotations

import math
import weakref

import torch
import warp as wp

from ..physics.contact import NORMAL_LATCHED, NORMAL_MASS_GRADIENT
from ..storage import Storage
from .fragment_boxes import FragmentBoxes


class BoxStorage(Storage):
    """`boxes` driven for simulator `sim` (held weakly)."""

    def __init__(self, sim, boxes: FragmentBoxes):
        self.sim = weakref.proxy(sim)  # the simulator owns its storage: no reference cycle
        self.boxes = boxes

    def fit(self, lower, upper, travel: float, slack: int) -> None:
        """Each fragment's box: its stencils plus the travel and the slack (`FragmentBoxes.fit` reads the node total
        and the overlap lists' length); the particles' common bounding box is not needed."""
        sim = self.sim
        P = sim.particles
        self.boxes.fit(P.x, P.fragment, 1 + math.ceil(travel / sim.grid.dx) + slack, sim.n_fragments)

    def whole_grid(self) -> bool:
        return False  # the boxes grow with the slack instead

    def on_latch(self, slack: int) -> None:
        """Boxes for the new fragments (the next frame's fit adds their travel)."""
        sim = self.sim
        P = sim.particles
        self.boxes.fit(P.x, P.fragment, 1 + slack, sim.n_fragments)

    def graph_key(self) -> tuple:
        return self.boxes.layout_key

    def p2g(self, only_fragment: int = -1, counts=None) -> None:
        """Every particle into its fragment's box, in runs of `options.p2g_run`; with the latched normals also the
        band masses their contact gate reads."""
        sim = self.sim
        w = sim.wp
        band = w["band"] if sim.normal_mode == NORMAL_LATCHED else None  # the latched gate's band masses
        run = sim.options.p2g_run
        self.boxes.p2g(w, sim.clock.view, w["counts"] if counts is None else counts, run, band_flags=band)

    def update(self) -> None:
        """Every fragment box's normalization, contact where fields meet, boundaries (`box_grid_update`)."""
        sim = self.sim
        g, c = sim.grid, sim.cfg.contact
        stats = (g.wp["stats"], g.wp["pair_stats"], g.pair_fragments) if sim.record_contact else None
        self.boxes.update(
            sim.clock.view, sim.eps_m, sim.gravity, c.fill * sim.node_mass, sim.wp["centroids"], sim.wp["counts"],
            sim.boundaries.colliders, e=float(sim.cfg.restitution), mu=float(c.friction), latched=sim.latched_normal,
            eps_b=sim.eps_b, project=bool(sim.spec.contact), stats=stats,
            mass_gradient=sim.normal_mode == NORMAL_MASS_GRADIENT, slots=sim.cfg.field_slots,
        )  # fmt: skip

    def g2p(self, only_fragment: int = -1) -> None:
        """Every particle from its own box; the next P2G's empty boxes are cleared beside it (G2P reads only
        velocities)."""
        sim = self.sim
        w, lo, hi = sim.wp, sim.lower, sim.upper
        if sim.options.concurrent:
            sim.fork.open()  # the next P2G's empty boxes go beside this G2P (which reads only velocities),
        sim.per_range(lambda a, b, c: self.boxes.g2p(w, sim.clock.view, lo, hi, c, a, b), False)
        with sim.beside():  # issued after it, so G2P's blocks take the SMs first and the clear fills its tail
            self.boxes.clear()
        sim.fork.join()

    def fields(self) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
        """A substep's fields at the current particles, as the slot storage's grid views give them after a substep
        (mass [K, X, Y, Z], momentum and velocity [K, X, Y, Z, 3], band mass [K, X, Y, Z]). The boxes are emptied
        right after each substep, so this deposits the particles again and runs the grid update (no G2P, no contact
        statistics, escapes counted apart), reads the fields and empties the boxes."""
        sim = self.sim
        record, sim.record_contact = sim.record_contact, False
        try:
            with sim._stream_scope():
                scratch = torch.zeros_like(sim.counts)  # escapes here are not the frame's
                self.p2g(counts=wp.from_torch(scratch))
                self.update()
                fields = self.boxes.dense(sim.n_fragments)
                self.boxes.clear()
        finally:
            sim.record_contact = record
        return fields
