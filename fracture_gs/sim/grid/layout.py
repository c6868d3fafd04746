"""The slot storage's layout: one owner, read by the grid, its kernels and the diagnostics.

Fields live in *slots* (DESIGN.md "Many fragments"). Slot 0 is dense: one (p, m) and one velocity
per node, for whichever fragment reached the node first in this substep's P2G (`owner`, the
fragment id + 1 in the low bits of a per-node word, 0 = free). A node that a second fragment
reaches gets a *row* of a compact pool, an open-addressing hash table keyed by the node's flat
index: the row holds slots 1 … S−1 (their owners, (p, m), velocities) plus the band mass of all S
slots, which the paper's contact gate reads. Only
nodes touched by two or more fragments (or by an interface-band particle) have a row, so memory
grows with the fractured surface, not with the grid or with K. `ROW_FLAG` in the owner word tells
the dense grid update that the node's fields finish in the pool pass (contact before boundaries).

One buffer per quantity holds the dense slots first and the pool slots after them, so a kernel
reaches any field with one index (`field_index`). Claims (owner words, pool rows, pool slot owners)
last a frame: every substep clears the accumulators only, so after a frame's first substep a
particle finds its slots with plain loads instead of compare-and-swap, and a particle whose 27 stencil
nodes all hold its own fragment in slot 0 skips the slot lookups altogether (the dense, unrolled
stencil; bitwise the same deposits); between frames the claims are reset (`Grid.reset_claims`). A slot whose
fragment moved away holds zero mass, which the grid
update treats as an inactive field. A fragment that finds no free slot at a node
deposits into slot 0 and reads it back there (mass and momentum conserved, that node's fields
merged): a *slot overflow*, counted every substep and reported, never silent. A pool that is
full is a *pool overflow*: the frame is redone with a larger pool.

Node boxes are (lo, hi) node ranges, hi exclusive. With one field (shared variants, or before a
latch) the owner word and the pool are not touched: the kernels take the dense path only.
"""

from __future__ import annotations

import warp as wp

OWNER_MASK = 0xFFFF  # low bits of the owner word: fragment id + 1 of slot 0 (0 = free)
ROW_FLAG = 0x10000  # the node has a pool row
EMPTY_KEY = -1  # a free pool row
MAX_PROBES = 64  # linear probing gives up here (a pool overflow, then a redo with a larger pool)


def box_volume(box: tuple) -> int:
    return max(0, box[3] - box[0]) * max(0, box[4] - box[1]) * max(0, box[5] - box[2])


def pool_capacity(rows: int) -> int:
    """Pool rows for `rows` expected multi-fragment nodes: twice that (load ≤ ½ keeps probing short),
    a power of two, at least 256."""
    c = 256
    while c < 2 * rows:
        c *= 2
    return c


@wp.func
def row_hash(n: int, mask: int):
    """First probe of node n in a pool of mask + 1 rows (Knuth's multiplicative hash, 31 bits)."""
    return ((n * 1640531527) & 0x7FFFFFFF) & mask


@wp.func
def find_row(key: wp.array(dtype=wp.int32), n: int, mask: int):
    """The pool row of node n, or −1 (no row)."""
    h = row_hash(n, mask)
    for _probe in range(MAX_PROBES):
        k = key[h]
        if k == n:
            return h
        if k == EMPTY_KEY:
            return -1
        h = (h + 1) & mask
    return -1


@wp.func
def claim_row(key: wp.array(dtype=wp.int32), owner: wp.array(dtype=wp.int32), n: int, mask: int):
    """The pool row of node n, inserted (lock-free compare-and-swap) if it has none; −1 when the
    pool is full. The inserting thread flags the node's owner word."""
    h = row_hash(n, mask)
    for _probe in range(MAX_PROBES):
        k = key[h]
        if k == n:
            return h
        if k == EMPTY_KEY:
            prev = wp.atomic_cas(key, h, EMPTY_KEY, n)
            if prev == EMPTY_KEY:
                wp.atomic_or(owner, n, ROW_FLAG)
                return h
            if prev == n:
                return h
        h = (h + 1) & mask
    return -1


@wp.func
def claim_slot0(owner: wp.array(dtype=wp.int32), n: int, k: int):
    """Fragment id + 1 that owns slot 0 of node n after trying to claim it for fragment k."""
    word = owner[n]
    for _try in range(8):
        if (word & OWNER_MASK) != 0:
            return word & OWNER_MASK
        prev = wp.atomic_cas(owner, n, word, word | (k + 1))
        if prev == word:
            return k + 1
        word = prev  # another thread changed the word (claimed slot 0, or flagged a row): look again
    return word & OWNER_MASK


@wp.func
def claim_pool_slot(pool_owner: wp.array(dtype=wp.int32), row: int, slots: int, k: int):
    """Slot j ∈ [1, slots) of fragment k in pool row `row` (claimed if free), or 0 when all are taken."""
    base = row * (slots - 1)
    for j in range(1, slots):
        o = pool_owner[base + j - 1]
        if o == k:
            return j
        if o == -1:
            prev = wp.atomic_cas(pool_owner, base + j - 1, -1, k)
            if prev == -1 or prev == k:
                return j
    return 0


@wp.func
def find_pool_slot(pool_owner: wp.array(dtype=wp.int32), row: int, slots: int, k: int):
    """Slot j ∈ [1, slots) of fragment k in pool row `row`, or 0 (the fragment deposited in slot 0)."""
    base = row * (slots - 1)
    for j in range(1, slots):
        if pool_owner[base + j - 1] == k:
            return j
    return 0


@wp.func
def field_index(n: int, row: int, j: int, n_nodes: int, slots: int):
    """Buffer index of slot j of node n (row: its pool row, read only when j > 0)."""
    if j == 0:
        return n
    return n_nodes + row * (slots - 1) + j - 1


@wp.struct
class GridView:
    """Everything a kernel needs to reach the fields (built by `Grid.view`, rebuilt when buffers move)."""

    mp: wp.array(dtype=wp.vec4)  # [X·Y·Z + C·(S−1)] (p, m): dense slot 0, then the pool's slots
    vel: wp.array(dtype=wp.vec3)  # [X·Y·Z + C·(S−1)] field velocities, same indexing
    owner: wp.array(dtype=wp.int32)  # [X·Y·Z] fragment + 1 of slot 0 | ROW_FLAG (multi-field grids)
    key: wp.array(dtype=wp.int32)  # [C] node of each pool row, EMPTY_KEY if free
    pool_owner: wp.array(dtype=wp.int32)  # [C·(S−1)] fragment of pool slots 1 … S−1, −1 if free
    band: wp.array(dtype=float)  # [C·S] band mass of slots 0 … S−1 of each row
    shape: wp.vec3i  # nodes per axis
    n_nodes: int  # X·Y·Z
    slots: int  # S = sim.field_slots (1 for a single-field grid)
    mask: int  # C − 1 (C a power of two)
    origin: wp.vec3  # node (0, 0, 0) [m]
    dx: float
    inv_dx: float
