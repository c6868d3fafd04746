"""The slot storage's lock-free claims (`grid.layout.claim_row`, `claim_slot0`, `claim_pool_slot`) when another
thread wins the race between a claim's load and its compare-and-swap. On a GPU thousands of particles claim the same
rows and words at once; on the CPU Warp runs the threads one after another, so these branches never run in a kernel
here. The rules they implement:

* `claim_row`: a row another thread inserted for the *same* node is that node's row (shared, never a second row);
  a row it inserted for *another* node is skipped and probing goes on at the next row; only the inserting thread
  flags the node's owner word; after MAX_PROBES occupied rows the pool is full (−1).
* `claim_slot0`: a word that changed under us (a row flag set) is read again and the claim retried, keeping the
  flag; a slot 0 another fragment took meanwhile belongs to that fragment.
* `claim_pool_slot`: a slot another thread took for the same fragment is ours; one taken for another fragment is
  skipped for the next; a full row answers 0 (deposit into slot 0).

The functions' own Python source is run with the two atomics replaced by ones that let a scripted "other thread"
write just before the swap (a Warp `@wp.func` is plain Python until Warp compiles it), so each interleaving is
reproduced exactly and deterministically."""

import types

from fracture_gs.sim.grid import layout
from fracture_gs.sim.grid.layout import EMPTY_KEY, MAX_PROBES, OWNER_MASK, ROW_FLAG

MASK = 255  # a pool of 256 rows


class _Race:
    """`wp.atomic_cas` / `wp.atomic_or` on Python lists, where another thread's writes (`cut_in[(id(array),
    index)]`: a list of values, one per swap attempt there) land between the caller's load and its swap."""

    def __init__(self, cut_in: dict | None = None):
        self.cut_in = {k: list(v) for k, v in (cut_in or {}).items()}
        self.swaps = 0

    def atomic_cas(self, arr, i, compare, value):
        pending = self.cut_in.get((id(arr), i))
        if pending:
            arr[i] = pending.pop(0)  # the other thread's write, just before ours
        self.swaps += 1
        old = arr[i]
        if old == compare:
            arr[i] = value
        return old

    def atomic_or(self, arr, i, bits):
        old = arr[i]
        arr[i] = old | bits
        return old


def _as_python(func, race: _Race):
    """The `@wp.func`'s Python body with `wp.atomic_*` from `race` and the Warp helpers it calls as Python."""
    f = func.func
    scope = dict(f.__globals__)
    scope["wp"] = types.SimpleNamespace(atomic_cas=race.atomic_cas, atomic_or=race.atomic_or)
    scope["row_hash"] = layout.row_hash.func
    return types.FunctionType(f.__code__, scope, f.__name__, f.__defaults__, f.__closure__)


def _home(n: int) -> int:
    return ((n * 1640531527) & 0x7FFFFFFF) & MASK


def _pool(n_nodes: int = 4096):
    return [EMPTY_KEY] * (MASK + 1), [0] * n_nodes


def test_claim_row_shares_a_row_another_thread_inserted_for_the_same_node():
    """Two threads insert node n at once; the other one's swap lands first. This thread gets the same row (its home
    row), no second row holds n, and this thread does not flag the owner word (the inserter did)."""
    key, owner = _pool()
    n = 1234
    h = _home(n)
    race = _Race({(id(key), h): [n]})
    got = _as_python(layout.claim_row, race)(key, owner, n, MASK)
    assert got == h
    assert key.count(n) == 1 and key[h] == n, "one row per node"
    assert owner[n] == 0, "only the thread whose swap inserted the key flags the owner word"


def test_claim_row_skips_a_row_another_thread_took_for_another_node():
    """The home row of n was empty when loaded, but another node's insert took it before the swap: n probes on and
    is inserted in the next row (wrapping from the last row to row 0), which this thread flags; the other node keeps
    its row."""
    n = next(m for m in range(2, 100_000) if _home(m) == MASK)  # home is the last row: the next one is row 0
    for other in (n + 1, 77):
        key, owner = _pool(200_000)
        race = _Race({(id(key), MASK): [other]})
        got = _as_python(layout.claim_row, race)(key, owner, n, MASK)
        assert got == 0, "the next row after the last is row 0"
        assert key[MASK] == other and key[0] == n
        assert owner[n] == ROW_FLAG


def test_claim_row_finds_its_own_row_without_a_swap_and_gives_up_after_max_probes():
    """A node already in the pool is found by loads alone (no swap); with rows occupied by other nodes from the home
    row on, a free row at probe MAX_PROBES − 1 is still claimed, while one at probe MAX_PROBES is past the limit:
    −1 (a pool overflow) and nothing written."""
    n = 999
    h = _home(n)
    key, owner = _pool()
    key[(h + 3) & MASK] = n
    for i in range(3):
        key[(h + i) & MASK] = 5000 + i
    race = _Race()
    assert _as_python(layout.claim_row, race)(key, owner, n, MASK) == (h + 3) & MASK
    assert race.swaps == 0 and owner[n] == 0

    for free_at, want in ((MAX_PROBES - 1, (h + MAX_PROBES - 1) & MASK), (MAX_PROBES, -1)):
        key, owner = _pool()
        for i in range(free_at):
            key[(h + i) & MASK] = 5000 + i
        before = list(key)
        got = _as_python(layout.claim_row, _Race())(key, owner, n, MASK)
        assert got == want, f"free row at probe {free_at}"
        if want < 0:
            assert key == before and owner[n] == 0, "a full pool is left as it was"
        else:
            assert key[want] == n and owner[n] == ROW_FLAG


def test_claim_slot0_retries_when_a_row_flag_lands_and_yields_to_a_fragment_that_claimed_first():
    """Fragment k claims a free slot 0. If another thread sets the node's row flag between the load and the swap,
    the swap fails, the word is read again and the claim succeeds with the flag kept (k + 1 | ROW_FLAG). If another
    fragment j claims slot 0 in that window, slot 0 is j's: the answer is j + 1 and the word keeps j's claim."""
    owner = [0, 0, 0]
    race = _Race({(id(owner), 1): [ROW_FLAG]})
    assert _as_python(layout.claim_slot0, race)(owner, 1, 4) == 5
    assert owner[1] == ROW_FLAG | 5 and race.swaps == 2

    owner = [0, 0, 0]
    race = _Race({(id(owner), 2): [ROW_FLAG | 8]})  # fragment 7 took slot 0 (and the row flag was set)
    assert _as_python(layout.claim_slot0, race)(owner, 2, 4) == 8
    assert owner[2] == ROW_FLAG | 8

    owner = [ROW_FLAG | 3]  # already owned: loads only
    race = _Race()
    assert _as_python(layout.claim_slot0, race)(owner, 0, 9) == 3 and race.swaps == 0
    assert owner[0] & OWNER_MASK == 3


def test_claim_pool_slot_keeps_a_slot_taken_for_the_same_fragment_and_skips_one_taken_for_another():
    """Row 2 of a pool with 3 slots per row (slots 1 … 3 at indices 6 … 8). Another thread of the same fragment
    taking slot 1 first: slot 1 is still this fragment's. Another fragment taking slot 1 first: this one gets slot 2.
    Other fragments taking every slot as this thread reaches it: 0 (deposit into slot 0). Rows 0, 1 and 3 are never
    touched."""
    slots = 4
    for cut, want, final in (
        ([6], 1, [6, -1, -1]),
        ([9], 2, [9, 6, -1]),
    ):
        pool = [-1] * 16
        race = _Race({(id(pool), 6): cut})
        assert _as_python(layout.claim_pool_slot, race)(pool, 2, slots, 6) == want
        assert pool[6:9] == final
        assert pool[:6] == [-1] * 6 and pool[9:] == [-1] * 7

    pool = [-1] * 16
    race = _Race({(id(pool), 6): [10], (id(pool), 7): [11], (id(pool), 8): [12]})
    assert _as_python(layout.claim_pool_slot, race)(pool, 2, slots, 6) == 0
    assert pool[6:9] == [10, 11, 12]
