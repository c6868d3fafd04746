"""Where the slot storage's pool puts a node's row (`grid.layout.row_hash`, `claim_row`, `find_row`): open
addressing keyed by the node's flat index, first probe Knuth's multiplicative hash h(n) = ((n · 1640531527) mod 2³¹)
& mask (int32 arithmetic, top bit cleared), then linear probing h + 1, h + 2, … wrapping from the last row to row
0. The tests' `simutil.fill_slots` writes rows at exactly these places for the kernels to find, so the placement
is a contract, not a detail. Driven by a one-thread kernel and compared with the rule simulated in Python."""

import torch
import warp as wp

from fracture_gs.runtime import ensure_warp
from fracture_gs.sim.grid.layout import EMPTY_KEY, ROW_FLAG, claim_row, find_row

ensure_warp()

MASK = 511  # a pool of 512 rows


def _hash(n: int) -> int:
    return ((n * 1640531527) & 0x7FFFFFFF) & MASK


@wp.kernel
def _insert_then_find(
    nodes: wp.array(dtype=wp.int32),
    key: wp.array(dtype=wp.int32),
    owner: wp.array(dtype=wp.int32),
    mask: int,
    rows: wp.array(dtype=wp.int32),
    found: wp.array(dtype=wp.int32),
):
    for i in range(nodes.shape[0]):  # one thread: the claims happen in list order
        rows[i] = claim_row(key, owner, nodes[i], mask)
    for i in range(nodes.shape[0]):
        found[i] = find_row(key, nodes[i], mask)
    found[nodes.shape[0]] = find_row(key, 1, mask)  # node 1 was never inserted


def test_rows_are_the_multiplicative_hash_then_linear_probing_with_wrap_around():
    """200 nodes (flat indices up to ~2·10⁵, so n · 1640531527 overflows int32) claimed one after the other into an
    empty pool of 512 rows, two of them hashing to the last row (the second wraps to row 0): each lands where the
    rule simulated in Python puts it, its owner word gets ROW_FLAG, `find_row` finds it there, and a node never
    inserted has no row (−1). The first probes cover odd and even rows alike (all 31 bits of the hash reach the
    mask)."""
    last = [n for n in range(2, 100_000) if _hash(n) == MASK][:2]
    nodes = last + [1009 * i + 7 for i in range(198)]
    assert 1 not in nodes and len(set(nodes)) == 200
    want, table = [], {}
    for n in nodes:
        h = _hash(n)
        while h in table:
            h = (h + 1) & MASK
        table[h] = n
        want.append(h)
    assert want[:2] == [MASK, 0], "the second node hashing to the last row wraps to row 0"
    assert {h % 2 for h in map(_hash, nodes)} == {0, 1}
    n_nodes = max(nodes) + 1
    key = wp.from_torch(torch.full((MASK + 1,), EMPTY_KEY, dtype=torch.int32))
    owner = wp.zeros(n_nodes, dtype=wp.int32, device="cpu")
    rows = wp.zeros(len(nodes), dtype=wp.int32, device="cpu")
    found = wp.zeros(len(nodes) + 1, dtype=wp.int32, device="cpu")
    idx = wp.from_torch(torch.tensor(nodes, dtype=torch.int32))
    wp.launch(_insert_then_find, dim=1, inputs=[idx, key, owner, MASK, rows, found], device="cpu")
    assert rows.numpy().tolist() == want
    assert found.numpy().tolist() == want + [-1]
    flags = owner.numpy()[nodes]
    assert (flags == ROW_FLAG).all(), "each inserted node's owner word carries ROW_FLAG (slot 0 still free)"
    assert int((owner.numpy() != 0).sum()) == len(nodes)
