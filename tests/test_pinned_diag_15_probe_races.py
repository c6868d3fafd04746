"""The voxel hash tables' probe (`sim.diagnostics.overlap_kernels.probe`): open addressing with linear probing,
insertion by compare-and-swap, including when another thread's swap lands between this thread's load and its own.

Rules: a key is found at the first slot from its home (Fibonacci hash) that holds it; a lookup (`create` false)
that meets an empty slot first answers −1 and writes nothing; an insertion claims the first empty slot; if another
thread filled that slot with the *same* key in the meantime, that slot is the key's (one slot per key); if it filled
it with *another* key, probing goes on at the next slot (the last slot wraps to slot 0) and the other key keeps its
slot. On the CPU Warp runs threads one after another, so the race branches never run in a kernel here: the
`@wp.func`'s own Python body is run with `wp.atomic_cas` replaced by one that lets a scripted other thread write
just before the swap, as `test_pinned_sim_7_claim_races.py` does for the grid's claims."""

import types

from fracture_gs.sim.diagnostics import overlap_kernels as ok

MASK = 63  # a table of 64 slots
EMPTY = -1


def _home(key: int, mask: int = MASK) -> int:
    """The Fibonacci hash written out: the top bits of key·⌊2⁶⁴/φ⌋ mod 2⁶⁴, from bit 33, masked."""
    return (((key * 11400714819323198485) % (1 << 64)) >> 33) & mask


class _Race:
    """`wp.atomic_cas` on a Python list; `cut_in[index]` is the value another thread writes there just before our
    swap (once)."""

    def __init__(self, cut_in=None):
        self.cut_in = dict(cut_in or {})
        self.swaps = 0

    def atomic_cas(self, arr, i, compare, value):
        if i in self.cut_in:
            arr[i] = self.cut_in.pop(i)
        self.swaps += 1
        old = arr[i]
        if old == compare:
            arr[i] = value
        return old


def _probe(race):
    f = ok.probe.func
    scope = dict(f.__globals__)
    scope.update(wp=types.SimpleNamespace(atomic_cas=race.atomic_cas), home=_home, EMPTY=EMPTY)
    return types.FunctionType(f.__code__, scope, f.__name__, f.__defaults__, f.__closure__)


def _table():
    return [EMPTY] * (MASK + 1)


def _key_homed_at(slot: int) -> int:
    return next(k for k in range(1, 1_000_000) if _home(k) == slot)


def test_an_insert_claims_the_home_slot_and_a_lookup_finds_it_there():
    """Into an empty table key k goes to its home slot by one swap; looking it up again (insert or lookup) returns
    that slot by loads alone; an absent key's lookup meets an empty slot and answers −1 without writing."""
    keys, k = _table(), 123456789
    race = _Race()
    h = _home(k)
    assert _probe(race)(keys, k, MASK, True) == h and keys[h] == k and race.swaps == 1
    assert _probe(race)(keys, k, MASK, True) == h and _probe(race)(keys, k, MASK, False) == h
    assert race.swaps == 1
    before = list(keys)
    absent = next(a for a in range(1, 10_000) if _home(a) != h)
    assert _probe(race)(keys, absent, MASK, False) == -1 and keys == before


def test_a_same_key_inserted_by_another_thread_meanwhile_is_this_keys_slot():
    """The home slot was empty when loaded but another thread inserted the same key before our swap: the swap fails
    with that key, and the slot is ours — the key is in the table once, at its home."""
    keys, k = _table(), 987654321
    h = _home(k)
    assert _probe(_Race({h: k}))(keys, k, MASK, True) == h
    assert keys.count(k) == 1 and keys[h] == k


def test_another_key_inserted_meanwhile_sends_the_insert_to_the_next_slot_wrapping_at_the_end():
    """Another thread put key j into our home slot between our load and our swap: we probe on and take the next
    slot, j keeps its slot. From the last slot the next one is slot 0."""
    for home in (10, MASK):
        keys, k = _table(), _key_homed_at(home)
        other = k + 7_000_001
        got = _probe(_Race({home: other}))(keys, k, MASK, True)
        nxt = (home + 1) & MASK
        assert got == nxt, home
        assert keys[home] == other and keys[nxt] == k and keys.count(k) == 1


def test_probing_passes_other_keys_and_a_lookup_stops_at_the_first_empty_slot():
    """Slots h, h+1 hold other keys: an insert of k lands at h+2, a lookup of k then finds h+2; once slot h+1 is
    empty again a lookup of a key homed at h that is not at h answers −1 (it stops at the hole)."""
    h = 20
    k = _key_homed_at(h)
    keys = _table()
    keys[h], keys[h + 1] = 11, 12
    assert _probe(_Race())(keys, k, MASK, True) == h + 2
    assert _probe(_Race())(keys, k, MASK, False) == h + 2
    keys[h + 1] = EMPTY
    assert _probe(_Race())(keys, k, MASK, False) == -1
