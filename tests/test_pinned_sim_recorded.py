"""`sim/recorded.py` on the CPU with a stand-in for CUDA graphs: the recording path (warm-up, capture,
replay, the bounded cache) runs here although no GPU is present, so its rules are pinned on every
machine. The stand-in behaves like a CUDA graph: capturing records the query's work on its output
buffer, a replay runs that work again on the buffers as they are now."""

import types

import pytest
import torch

from fracture_gs.sim import recorded as R


class _Graph:
    """A CUDA graph stand-in: the work registered while it captures, run again by `replay`."""

    active = None

    def __init__(self):
        self.ops, self.replays = [], 0

    def replay(self):
        self.replays += 1
        for op in self.ops:
            op()


class _Capture:
    def __init__(self, graph, stream=None, capture_error_mode=None):
        self.graph = graph

    def __enter__(self):
        _Graph.active = self.graph

    def __exit__(self, *exc):
        _Graph.active = None


class _NoStream:
    def __init__(self, stream):
        pass

    def __enter__(self):
        return None

    def __exit__(self, *exc):
        return None


@pytest.fixture
def fake_cuda(monkeypatch):
    """`Recorded` on a "cuda" device whose graphs are `_Graph`s (the module's torch.cuda and stream helpers
    replaced; everything else in torch is the real one)."""
    fake_torch = types.SimpleNamespace(cuda=types.SimpleNamespace(CUDAGraph=_Graph, graph=_Capture, stream=_NoStream))
    monkeypatch.setattr(R, "torch", fake_torch)
    monkeypatch.setattr(R, "side_stream", lambda device, purpose: None)
    monkeypatch.setattr(R, "warp_stream", lambda device: None)
    monkeypatch.setattr(R, "ensure_warp", lambda: None)


def _query(x, k, calls):
    """A query writing k·Σx into its own output buffer (as a recorded query must), counting its calls."""
    out = torch.zeros(3, dtype=torch.float64)

    def work():
        out.copy_((x * k).sum(0))

    def fn():
        calls[k] = calls.get(k, 0) + 1
        work()
        if _Graph.active is not None:
            _Graph.active.ops.append(work)
        return out

    return fn


def test_recorded_query_captures_once_then_replays_on_the_current_state(fake_cuda):
    """A new key runs the query twice (warm-up outside the capture, then the capture) and replays the
    graph once; later calls with the same key only replay, and the answer follows the state as it moves
    in place, equal to running the query again."""
    x = torch.rand(50, 3, dtype=torch.float64)
    rec, calls = R.Recorded("cuda:0"), {}
    assert rec.records
    fns = {k: _query(x, k, calls) for k in (1, 2)}
    for _ in range(3):
        x.add_(0.25)
        for k in (1, 2):
            got = rec(k, fns[k])
            assert torch.equal(got, (x * k).sum(0))
    assert calls == {1: 2, 2: 2}  # warm-up + capture once per key, never again
    assert [rec.graphs[k][0].replays for k in (1, 2)] == [3, 3]


def test_recorded_cache_keeps_the_eight_most_recently_used_keys(fake_cuda):
    """By default the cache holds 8 graphs (each holds device memory): a ninth key evicts the least
    recently used one, and using a key again makes it the most recent."""
    x = torch.rand(10, 3, dtype=torch.float64)
    rec, calls = R.Recorded("cuda:0"), {}
    fns = {k: _query(x, k, calls) for k in range(10)}
    for k in range(8):
        rec(k, fns[k])
    assert list(rec.graphs) == list(range(8))
    rec(0, fns[0])  # 0 becomes the most recent: 1 is now the oldest
    rec(8, fns[8])
    assert len(rec.graphs) == 8
    assert list(rec.graphs) == [2, 3, 4, 5, 6, 7, 0, 8]
    assert calls[0] == 2  # the hit on 0 did not record again
    rec(1, fns[1])  # evicted: recorded anew
    assert calls[1] == 4


def test_recorded_with_keep_one_records_each_alternating_key_anew(fake_cuda):
    """`keep` bounds the cache: with keep = 1, alternating between two keys records every call anew and
    still answers correctly."""
    x = torch.rand(10, 3, dtype=torch.float64)
    rec, calls = R.Recorded("cuda:0", keep=1), {}
    fns = {k: _query(x, k, calls) for k in (1, 2)}
    for _ in range(2):
        for k in (1, 2):
            assert torch.equal(rec(k, fns[k]), (x * k).sum(0))
    assert len(rec.graphs) == 1
    assert calls == {1: 4, 2: 4}


def test_recorded_on_the_cpu_runs_the_query_and_stores_nothing():
    """On a CPU device nothing is recorded: every call runs the query itself."""
    x = torch.rand(10, 3, dtype=torch.float64)
    rec, calls = R.Recorded("cpu"), {}
    fn = _query(x, 1, calls)
    for _ in range(3):
        rec("k", fn)
    assert not rec.records and calls == {1: 3} and rec.graphs == {}
