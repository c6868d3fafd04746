"""Pinned rules of the sweep's launch and store protocol (`fracture_gs.sweep.distributed`): which `--device` values
exist on a machine of K GPUs and what the refusal says, the heartbeat's timeout measured exactly from a rank's
last beat, a rank told to abort by rank 0 (or finding it dead) leaving the process group alone, rank 0's
failure report, the one-process coordinator, and meeting the other ranks.

Unit-level calls only: the GPU count is faked, the heartbeat loop runs on the test's thread against a scripted
clock and an in-memory store, and no process group is made.
"""

from __future__ import annotations

import datetime
import json
import time
from types import SimpleNamespace

import pytest
from test_pinned_sweep import FakeStore, coordinator

from fracture_gs.sweep import distributed as D

# ---------------------------------------------------------------------------------------------
# --device


def gpus(monkeypatch, count, why=""):
    monkeypatch.setattr(D, "_cuda", lambda: (count, why))


@pytest.mark.parametrize("count", [1, 2, 4])
def test_cuda_n_exists_for_n_below_the_gpu_count(monkeypatch, count):
    """cuda:N names one of K GPUs for N = 0 .. K-1: the last one is accepted, N = K is refused with the range that
    exists (cuda:0 to cuda:K-1) and the fix."""
    gpus(monkeypatch, count)
    assert D.resolve_device(f"cuda:{count - 1}", D.Launch()) == f"cuda:{count - 1}"
    with pytest.raises(D.LaunchError) as info:
        D.resolve_device(f"cuda:{count}", D.Launch())
    assert str(info.value) == (
        f"--device cuda:{count} does not exist; this machine has {count} CUDA device(s), cuda:0 to "
        f"cuda:{count - 1}; pick one of those, or cpu."
    )


def test_without_a_gpu_auto_is_the_cpu_and_cuda_is_refused_saying_why(monkeypatch):
    """With no GPU, auto (also no flag) is the CPU, while cuda and cuda:0 are refused naming why there is none
    and the fix (cpu)."""
    gpus(monkeypatch, 0, "torch.cuda.is_available() is False: a CPU-only torch build")
    assert D.resolve_device(None, D.Launch()) == "cpu" and D.resolve_device("auto", D.Launch()) == "cpu"
    with pytest.raises(D.LaunchError) as info:
        D.resolve_device("cuda:0", D.Launch())
    assert str(info.value) == (
        "--device cuda:0 does not exist; this machine has no CUDA device (torch.cuda.is_available() is False: "
        "a CPU-only torch build); use cpu."
    )
    with pytest.raises(D.LaunchError, match=r"^--device cuda was requested but this machine has no CUDA device \("):
        D.resolve_device("cuda", D.Launch())


def test_cuda_gives_each_rank_its_local_gpu_while_they_fit(monkeypatch):
    """--device cuda (and auto) gives rank r of a node cuda:LOCAL_RANK while the node's ranks fit its GPUs (as
    many ranks as GPUs is fine); one rank more is refused naming both counts, the reason when there is one,
    and the torchrun fix."""
    gpus(monkeypatch, 2)
    last = D.Launch(rank=3, world_size=4, local_rank=1, local_world_size=2, master="h:1")
    assert D.resolve_device("cuda", last) == "cuda:1" and D.resolve_device("auto", last) == "cuda:1"
    three = D.Launch(rank=0, world_size=3, local_rank=0, local_world_size=3, master="h:1")
    with pytest.raises(D.LaunchError) as info:
        D.resolve_device("cuda", three)
    assert str(info.value) == (
        "3 ranks were started on this node but it has 2 GPU(s); start one rank per GPU "
        "(torchrun --nproc-per-node 2) or use --device cpu."
    )
    gpus(monkeypatch, 2, "CUDA_VISIBLE_DEVICES=0,1")
    with pytest.raises(D.LaunchError, match=r"it has 2 GPU\(s\) \(CUDA_VISIBLE_DEVICES=0,1\); start one"):
        D.resolve_device("cuda", three)


# ---------------------------------------------------------------------------------------------
# the heartbeat


class Steps:
    """The heartbeat's stop event: records what the coordinator holds after each round, runs `between(k)` and
    ends the loop after `rounds` rounds."""

    def __init__(self, coord, rounds, between=lambda k: None):
        self.coord, self.rounds, self.between, self.seen = coord, rounds, between, []

    def wait(self, timeout):
        self.seen.append(dict(self.coord.dead))
        self.between(len(self.seen))
        return len(self.seen) >= self.rounds

    def set(self):
        pass


def scripted_clock(monkeypatch, times):
    ticks = iter(times)
    monkeypatch.setattr(D, "time", SimpleNamespace(monotonic=lambda: next(ticks), sleep=time.sleep))


def test_a_rank_is_dead_only_when_silent_for_longer_than_the_timeout(monkeypatch):
    """Rank 0 counts a rank's silence from its last beat: a rank that beat at t = 8 s is alive at t = 18 s (silent
    for exactly the 10 s timeout) and dead at 18.25 s, with a message naming the timeout; rank 0 bumps its own
    counter once a round."""
    coord = coordinator(0, 2, timeout_s=10.0)
    scripted_clock(monkeypatch, [0.0, 0.0, 8.0, 18.0, 18.25])

    def between(k):
        if k == 1:  # rank 1 beats once, between the first and the second round
            coord.store.add(coord._key("beat", 1), 1)

    coord._stop = Steps(coord, 4, between)
    coord._heartbeat()
    dead = {1: "sent no heartbeat for 10 s (it died or hangs)"}
    assert coord._stop.seen == [{}, {}, {}, dead]
    assert int(coord.store.get(coord._key("beat", 0))) == 4


def test_a_non_zero_rank_watches_rank_zero_only(monkeypatch):
    """A rank other than 0 watches rank 0 alone: rank 2 never beating is not its business, rank 0 silent past the
    timeout is dead."""
    coord = coordinator(1, 3, timeout_s=1.0)
    scripted_clock(monkeypatch, [0.0, 0.0, 0.5, 1.5])
    coord._stop = Steps(coord, 3)
    coord._heartbeat()
    assert coord._stop.seen == [{}, {}, {0: "sent no heartbeat for 1 s (it died or hangs)"}]


class GoneStore(FakeStore):
    def add(self, key, n):
        raise ConnectionError("Connection reset by peer")


def test_a_store_that_stops_answering_ends_the_heartbeat(monkeypatch):
    """When the store stops answering, a rank other than 0 marks rank 0 dead naming the store's address and the
    error; rank 0 (which hosts the store) marks itself failed, so close leaves the process group alone."""
    import torch.distributed as dist

    one = coordinator(1, 2)
    one.store = GoneStore()
    one._heartbeat()
    assert one.dead == {0: "stopped answering: the store at h:1 is gone (Connection reset by peer)"}
    zero = coordinator(0, 2)
    zero.store = GoneStore()
    zero._heartbeat()
    assert zero._failed and zero.dead == {}
    calls = []
    monkeypatch.setattr(dist, "is_initialized", lambda: True)
    monkeypatch.setattr(dist, "destroy_process_group", lambda *a, **k: calls.append(1))
    zero.close()
    assert calls == []


# ---------------------------------------------------------------------------------------------
# abort


def test_a_rank_told_to_abort_fails_with_rank_zeros_reason_and_keeps_the_group(monkeypatch):
    """Rank 0 that gives up while planning leaves an abort note; a rank waiting for the plan raises a RankFailure
    with that note (blamed on rank 0) and counts as failed, so its close does not tear down the process group
    (which would wait on ranks that are gone); a rank that planned normally does tear it down."""
    import torch.distributed as dist

    calls = []
    monkeypatch.setattr(dist, "is_initialized", lambda: True)
    monkeypatch.setattr(dist, "destroy_process_group", lambda *a, **k: calls.append(1))
    one = coordinator(1, 2)
    one.store.set(one._key("abort"), "rank 2 of 3 sent no heartbeat")
    with pytest.raises(D.RankFailure) as info:
        one.plan({}, lambda s: pytest.fail("only rank 0 plans"))
    assert str(info.value) == "rank 2 of 3 sent no heartbeat" and info.value.rank == 0
    one.close()
    assert calls == []
    fine = coordinator(1, 2)
    fine.store.set(fine._key("plan"), json.dumps({"p": 1}))
    assert fine.plan({}, lambda s: None) == {"p": 1}
    fine.close()
    assert calls == [1]


# ---------------------------------------------------------------------------------------------
# rank 0 gone, one process, meeting


def test_a_rank_whose_rank_zero_is_dead_fails_naming_rank_zero_and_what_it_was_doing():
    """A rank other than 0 that finds rank 0 dead stops, whether waiting for the plan or about to hand over its
    rows: a RankFailure naming rank 0, why it counts as dead, this rank, what it was doing, and that the finished
    cells are cached; it publishes no rows."""
    one = coordinator(1, 3)
    one.dead[0] = "stopped answering"
    with pytest.raises(D.RankFailure) as info:
        one.plan({}, lambda s: pytest.fail("only rank 0 plans"))
    assert info.value.rank == 0 and str(info.value) == (
        "rank 0 of 3 stopped answering (seen from rank 1) while waiting for rank 0's plan; the cells every live "
        "rank finished are cached, so rerunning the same command resumes from them."
    )
    with pytest.raises(D.RankFailure, match=r"^rank 0 of 3 stopped answering \(seen from rank 1\) while this rank ran"):
        one.finish({"a": {"status": "ok"}})
    assert not one.store.check([one._key("rows", 1)]) and not one.store.check([one._key("done", 1)])


def test_rank_zero_reports_no_failure_when_every_rank_finished():
    """After gathering, rank 0's failure() is None when no rank died, else the lowest dead rank's RankFailure."""
    zero = coordinator(0, 3)
    assert zero.failure() is None
    zero.dead.update({2: "sent no heartbeat for 300 s (it died or hangs)", 1: "stopped"})
    failure = zero.failure()
    assert failure.rank == 1 and str(failure).startswith("rank 1 of 3 stopped (seen from rank 0) while the sweep ran")


def test_one_process_needs_no_store():
    """One process plans from its own cache alone, gathers its own rows, never fails, and a launch without
    WORLD_SIZE > 1 gets this plain coordinator."""
    coord = D.coordinator(D.Launch(), "cpu")
    assert type(coord) is D.Coordinator
    with coord as c:
        assert c.plan({"x": "ok"}, lambda statuses: {"statuses": statuses}) == {"statuses": [{"x": "ok"}]}
        assert c.finish({"x": {"status": "ok"}}) == [{"x": {"status": "ok"}}] and c.failure() is None
    assert type(D.coordinator(D.Launch(0, 2, 0, 2, "h:1"), "cpu", 5.0, 0.5)) is D.StoreCoordinator


def test_meeting_the_other_ranks_starts_the_heartbeat_on_the_groups_store(monkeypatch):
    """Entering a store coordinator on the CPU makes a gloo process group with this rank, the world size and the
    rank timeout, takes the group's store and starts beating on it; close stops the heartbeat and destroys the
    group."""
    import torch.distributed as dist
    from torch.distributed import distributed_c10d

    calls, store = [], FakeStore()
    monkeypatch.setattr(dist, "init_process_group", lambda backend, **kw: calls.append((backend, kw)))
    monkeypatch.setattr(distributed_c10d, "_get_default_store", lambda: store)
    monkeypatch.setattr(dist, "is_initialized", lambda: True)
    monkeypatch.setattr(dist, "destroy_process_group", lambda *a, **k: calls.append("destroyed"))
    coord = D.StoreCoordinator(D.Launch(1, 2, 1, 2, "h:1"), "cpu", timeout_s=42.0, beat_s=0.01)
    with coord:
        deadline = time.monotonic() + 5.0
        while int(store.data.get(coord._key("beat", 1), b"0")) < 3 and time.monotonic() < deadline:
            time.sleep(0.01)
        assert coord.backend == "gloo" and coord.store is store
        assert int(store.get(coord._key("beat", 1))) >= 3
    assert calls == [("gloo", {"rank": 1, "world_size": 2, "timeout": datetime.timedelta(seconds=42)}), "destroyed"]
    assert not coord._thread.is_alive()
