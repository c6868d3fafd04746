"""What every grid storage shares with the solver: the counters its launches bump and the most fields a node holds.

The counters are one int32 device array (`Simulator.counts`), read once per frame with the frame's check: P2G counts
the particles whose stencil left the grid work's box (the frame is redone with more room), G2P the particles clamped
to the domain walls, a storage the deposits that found no free slot and the pool insertions that failed.
"""

from __future__ import annotations

MAX_SLOTS = 8  # compile-time bound on sim.field_slots: the fields a node couples (registers of the contact pass)

# solver counters (int32, one device array; read once per frame)
COUNT_CLAMPED, COUNT_ESCAPED, COUNT_SLOT_OVERFLOW, COUNT_POOL_OVERFLOW = range(4)
N_COUNTS = 4
