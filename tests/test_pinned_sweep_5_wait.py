"""Pinned rules of a rank waiting for other ranks' keys in the store (`StoreCoordinator._wait`), round five:

- keys that all exist end the wait at once, even when their owner has died since (its work is there);
- a missing key whose owner is dead ends the wait with a RankFailure naming that owner;
- on a rank other than 0, rank 0 dead ends any wait with a RankFailure naming rank 0, whoever owns the keys
  (rank 0 is the coordinator: without it nothing more will come);
- on a rank other than 0, an abort posted by rank 0 ends the wait with a RankFailure carrying rank 0's text;
  rank 0 itself (which posts it) keeps waiting for its keys;
- a wait that raises marks the coordinator failed (its process group is then not torn down collectively).

In-memory store (`FakeStore`); each wait runs in a thread joined within two seconds, so a wait that should end
and does not fails the test instead of hanging it.
"""

from __future__ import annotations

import threading

from test_pinned_sweep import coordinator, publish_later

from fracture_gs.sweep import distributed as D


def wait(coord, keys, owners, doing="testing", patience=2.0):
    """('returned', None) or ('raised', the RankFailure), or ('waiting', None) if still waiting after `patience`
    seconds."""
    result = []

    def body():
        try:
            coord._wait(keys, owners, doing)
            result.append(("returned", None))
        except D.RankFailure as exc:
            result.append(("raised", exc))

    thread = threading.Thread(target=body, daemon=True)
    thread.start()
    thread.join(patience)
    return result[0] if result else ("waiting", None)


def test_keys_that_exist_end_the_wait_even_if_their_owner_has_died():
    """Rank 0 waiting for rank 1's key, which rank 1 posted before dying: the wait returns, nothing failed."""
    coord = coordinator(0, 3)
    coord.store.set(coord._key("cached", 1), "{}")
    coord.dead[1] = "sent no heartbeat for 300 s (it died or hangs)"
    assert wait(coord, [coord._key("cached", 1)], [1]) == ("returned", None)
    assert not coord._failed


def test_a_missing_key_of_a_dead_owner_is_a_failure_naming_that_owner():
    """Rank 0 waits for ranks 1 and 2; rank 1's key is there, rank 2's is missing and rank 2 is dead: a
    RankFailure names rank 2, its reason, the rank that saw it and what it was waiting for."""
    coord = coordinator(0, 3)
    coord.store.set(coord._key("cached", 1), "{}")
    coord.dead[2] = "sent no heartbeat for 300 s (it died or hangs)"
    how, exc = wait(coord, [coord._key("cached", 1), coord._key("cached", 2)], [1, 2], "listing the cache")
    assert how == "raised" and exc.rank == 2 and coord._failed
    assert str(exc).startswith(
        "rank 2 of 3 sent no heartbeat for 300 s (it died or hangs) (seen from rank 0) while listing the cache; "
    )


def test_rank_zero_dead_ends_any_wait_of_another_rank():
    """Rank 1 waiting for a key of rank 2 (alive, not yet posted) when rank 0 has died: the wait ends with a
    RankFailure naming rank 0, not a wait for ever."""
    coord = coordinator(1, 3)
    coord.dead[0] = "stopped answering: the store at h:1 is gone (gone)"
    how, exc = wait(coord, [coord._key("rows", 2)], [2], "gathering")
    assert how == "raised" and exc.rank == 0 and coord._failed
    assert "rank 0 of 3 stopped answering" in str(exc) and "(seen from rank 1) while gathering" in str(exc)


def test_another_rank_stops_on_rank_zeros_abort_and_rank_zero_does_not():
    """With rank 0's abort posted: rank 1 waiting for the plan raises a RankFailure with the abort's text,
    attributed to rank 0; rank 0, waiting for a key of rank 1 that comes later, returns when it comes."""
    one = coordinator(1, 2)
    one.store.set(one._key("abort"), "rank 1 of 2 died while listing")
    how, exc = wait(one, [one._key("plan")], [0])
    assert how == "raised" and exc.rank == 0 and str(exc) == "rank 1 of 2 died while listing" and one._failed
    zero = coordinator(0, 2)
    zero.store.set(zero._key("abort"), "an earlier abort")
    publish_later(zero.store, [(zero._key("cached", 1), "{}")], delay=0.3)
    assert wait(zero, [zero._key("cached", 1)], [1]) == ("returned", None)
    assert not zero._failed


def test_a_live_owners_missing_key_is_waited_for():
    """Nobody dead, no abort: rank 1 keeps waiting for rank 0's plan (still waiting after half a second, several
    polls) until it is posted, then returns."""
    one = coordinator(1, 2)
    assert wait(one, [one._key("plan")], [0], patience=0.5)[0] == "waiting"
    one.store.set(one._key("plan"), "{}")
    assert wait(one, [one._key("plan")], [0]) == ("returned", None)
    assert not one._failed
