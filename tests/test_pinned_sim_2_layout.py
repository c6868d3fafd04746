"""The multi-field grid's node bookkeeping (`sim.grid.layout`), driven one call at a time from a one-thread kernel:
slot 0's owner is the low 16 bits of the node's owner word (the pool-row flag is not a fragment), a node without
a pool row has none (−1), and a fragment finds again the pool slot it claimed, the next fragment taking the next
free slot of the same row."""

import torch
import warp as wp

from fracture_gs.runtime import ensure_warp
from fracture_gs.sim.grid.layout import EMPTY_KEY, ROW_FLAG, claim_pool_slot, claim_row, claim_slot0, find_row

ensure_warp()


@wp.kernel
def _script(
    owner: wp.array(dtype=wp.int32),
    key: wp.array(dtype=wp.int32),
    pool_owner: wp.array(dtype=wp.int32),
    out: wp.array(dtype=wp.int32),
):
    out[0] = find_row(key, 5, 7)  # empty pool: no row
    out[1] = claim_row(key, owner, 5, 7)  # inserts node 5 and flags its owner word
    out[2] = find_row(key, 5, 7)
    out[3] = claim_slot0(owner, 5, 2)  # slot 0 still free: fragment 2 takes it (id + 1 = 3)
    out[4] = claim_slot0(owner, 5, 4)  # taken: the owner stays fragment 2
    out[5] = claim_pool_slot(pool_owner, 1, 4, 5)  # row 1, slots 1..3
    out[6] = claim_pool_slot(pool_owner, 1, 4, 6)
    out[7] = claim_pool_slot(pool_owner, 1, 4, 5)  # found again
    out[8] = claim_pool_slot(pool_owner, 1, 4, 7)
    out[9] = claim_pool_slot(pool_owner, 1, 4, 8)  # row full


def test_owner_words_rows_and_pool_slots_follow_their_claims():
    """A node's owner word holds ROW_FLAG once the node has a pool row and, in its low bits, fragment id + 1
    of slot 0: a flagged node's slot 0 is still free and the first fragment to ask takes it, the next is told
    who owns it. `find_row` answers −1 in an empty pool and the claimed row after `claim_row`. Pool slots of a
    row are handed out 1, 2, 3 in claim order, a fragment asking again gets its own slot back, and a full row
    answers 0."""
    owner = wp.zeros(8, dtype=wp.int32, device="cpu")
    key = wp.from_torch(torch.full((8,), EMPTY_KEY, dtype=torch.int32))
    pool_owner = wp.from_torch(torch.full((8 * 3,), -1, dtype=torch.int32))
    out = wp.zeros(10, dtype=wp.int32, device="cpu")
    wp.launch(_script, dim=1, inputs=[owner, key, pool_owner, out], device="cpu")
    got = out.numpy().tolist()
    row = got[1]
    assert 0 <= row < 8
    assert got[:5] == [-1, row, row, 3, 3]
    assert got[5:] == [1, 2, 1, 3, 0]
    assert int(owner.numpy()[5]) == ROW_FLAG | 3
    assert pool_owner.numpy()[3:6].tolist() == [5, 6, 7]


@wp.kernel
def _find(key: wp.array(dtype=wp.int32), n: int, mask: int, out: wp.array(dtype=wp.int32)):
    out[0] = find_row(key, n, mask)


def test_a_node_missing_from_a_full_pool_has_no_row():
    """Linear probing gives up after MAX_PROBES rows: in a pool of 64 rows all held by other nodes, node 5 has
    no row (−1), not row 0 of some other node; a node that is there is found."""
    key = wp.from_torch(torch.arange(100, 164, dtype=torch.int32))
    out = wp.zeros(1, dtype=wp.int32, device="cpu")
    wp.launch(_find, dim=1, inputs=[key, 5, 63, out], device="cpu")
    assert int(out.numpy()[0]) == -1
    wp.launch(_find, dim=1, inputs=[key, 130, 63, out], device="cpu")
    assert int(out.numpy()[0]) == 30
