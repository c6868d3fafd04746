"""The fragment-aware overlap's hash table lookup (`sim.diagnostics.overlap_kernels.probe`), driven one call at a
time from a one-thread kernel: a key is inserted (with `create`) at its first probe, Fibonacci hashing
⌊(key · 11400714819323198485 mod 2⁶⁴) / 2³³⌋ & mask, or the next free slot after it, wrapping from the last slot
to slot 0; it is found again there; an absent key is −1, both when probing reaches an empty slot and when every
slot of a full table holds another key (never a slot index, which a caller would read as someone else's entry)."""

import torch
import warp as wp

from fracture_gs.runtime import ensure_warp
from fracture_gs.sim.diagnostics.overlap_kernels import probe

ensure_warp()

MASK = 7  # an 8-slot table


def _home(key: int) -> int:
    return (((key * 11400714819323198485) % (1 << 64)) >> 33) & MASK


@wp.kernel
def _probe(
    keys: wp.array(dtype=wp.int64),
    queries: wp.array(dtype=wp.int64),
    create: wp.array(dtype=wp.int32),
    out: wp.array(dtype=wp.int32),
):
    for i in range(queries.shape[0]):  # one thread, in order
        out[i] = probe(keys, queries[i], MASK, create[i] != 0)


def _run(keys, script):
    table = wp.from_torch(torch.tensor(keys, dtype=torch.int64))
    q = wp.from_torch(torch.tensor([s[0] for s in script], dtype=torch.int64))
    c = wp.from_torch(torch.tensor([int(s[1]) for s in script], dtype=torch.int32))
    out = wp.zeros(len(script), dtype=wp.int32, device="cpu")
    wp.launch(_probe, dim=1, inputs=[table, q, c, out], device="cpu")
    return out.numpy().tolist(), table.numpy().tolist()


def test_keys_go_to_their_first_probe_or_the_next_free_slot_and_absent_keys_are_minus_one():
    """Two keys whose first probe is the last slot: the first lands there, the second wraps to slot 0; a key homed
    at slot 0 then goes to slot 1. Each is found again at its slot; a key never inserted is −1 and is not added."""
    last = [k for k in range(1, 10_000) if _home(k) == MASK][:2]
    zero = next(k for k in range(1, 10_000) if _home(k) == 0)
    absent = next(k for k in range(1, 10_000) if k not in last and k != zero)
    script = [(last[0], True), (last[1], True), (zero, True), (last[1], False), (zero, False), (last[0], False)]
    script += [(absent, False), (absent, False)]
    got, table = _run([-1] * (MASK + 1), script)
    assert got == [MASK, 0, 1, 0, 1, MASK, -1, -1]
    assert table == [last[1], zero] + [-1] * (MASK - 2) + [last[0]]


def test_an_absent_key_in_a_full_table_is_minus_one():
    """Every slot holds another key: looking up (or, impossibly, inserting) a key that is not there visits all
    eight slots and answers −1, while each key that is there is still found at its slot."""
    keys = list(range(100, 108))
    got, table = _run(keys, [(5, False), (5, True)] + [(k, False) for k in keys])
    assert got == [-1, -1] + list(range(8))
    assert table == keys
