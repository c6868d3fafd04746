"""The grid storage a substep transfers through: one interface (`Storage`), two implementations, and what every
storage shares with the solver (the counters its launches bump, the most fields a node couples).

- `grid.slots.SlotStorage`: the dense grid, and after a latch the slot storage of fragment fields (slot 0 dense, a
  pool of rows where fragments meet). Every simulator has one: it holds the single field before a latch.
- `boxes.storage.BoxStorage`: a dense box per fragment (`sim.grid_storage = "boxes"` or `"auto"`), after a latch.

A substep is `p2g`, `update`, `g2p`: launches only (safe inside a CUDA graph capture), Δt and t from the simulator's
clock. Between frames `fit` sizes the grid work for the frame (host reads allowed, buffers may move), and
`graph_key` names what the recorded launches bake in. A storage reads its simulator's state (the particles' Warp
views `wp`, the clock, the counters, the contact settings, `options`) and launches through it
(`Simulator.launch`, `beside`, `per_range`); it holds a weak reference, so no cycle keeps a simulator alive.

The counters are one int32 device array (`Simulator.counts`), read once per frame with the frame's check: P2G counts
the particles whose stencil left the grid work's box (the frame is redone with more room), G2P the particles clamped
to the domain walls, a storage the deposits that found no free slot and the pool insertions that failed.
"""

from __future__ import annotations

from abc import ABC, abstractmethod

MAX_SLOTS = 8  # compile-time bound on sim.field_slots: the fields a node couples (registers of the contact pass)

# solver counters (int32, one device array; read once per frame)
COUNT_CLAMPED, COUNT_ESCAPED, COUNT_SLOT_OVERFLOW, COUNT_POOL_OVERFLOW = range(4)
N_COUNTS = 4


class Storage(ABC):
    """Where a substep's fields live: P2G, the grid update and G2P, and their fit between frames."""

    @abstractmethod
    def fit(self, lower, upper, travel: float, slack: int) -> None:
        """Between frames: fit the grid work to the particles' bounding box `lower`, `upper` (per axis [m]), the
        distance they can travel this frame `travel` [m] and `slack` more cells (grown by redone frames)."""

    @abstractmethod
    def whole_grid(self) -> bool:
        """After a frame's second escape: take the whole grid for the grid work, where no stencil can escape (True),
        or leave it to `fit`'s growing slack (False)."""

    @abstractmethod
    def on_latch(self, slack: int) -> None:
        """After a latch of a multi-field variant (new fragment ids, new routing): make room for the fields."""

    @abstractmethod
    def p2g(self, only_fragment: int = -1, counts=None) -> None:
        """Reset the fields and scatter the particles into them (Eq. multifield_p2g); `only_fragment` ≥ 0: that
        fragment's particles alone (the global fragment pass); `counts`: another counter array (Warp int32)."""

    @abstractmethod
    def update(self) -> None:
        """Normalize (v = p/m + Δt g), the contact between fields that meet, the boundaries."""

    @abstractmethod
    def g2p(self, only_fragment: int = -1) -> None:
        """Gather v, C, F's update and x of every particle from its own field (Eq. field_g2p)."""

    @abstractmethod
    def graph_key(self) -> tuple:
        """What the recorded launches bake in besides the clock (buffers, launch sizes): a change records again."""
