"""`sim/diff/solver.py` host helpers: Warp's CUDA pool is told to keep a recorded frame's worth of freed
memory (48 KiB per particle) and the threshold only ever rises; the cyclic garbage collector is held off
while a tape records and restored after, even when the frame raises. Warp's pool functions are replaced
by a recorder (no GPU needed)."""

import gc
import types

import pytest

from fracture_gs.sim.diff import solver as S


def _pool(monkeypatch, threshold, enabled=True):
    calls = []
    fake = types.SimpleNamespace(
        is_mempool_enabled=lambda device: enabled,
        get_mempool_release_threshold=lambda device: threshold,
        set_mempool_release_threshold=lambda device, value: calls.append(value),
    )
    monkeypatch.setattr(S, "wp", fake)
    return calls


def test_tape_memory_threshold_rises_to_48_kib_per_particle_and_never_falls(monkeypatch):
    """1,000 particles need 48 KiB each kept: a lower threshold is raised to 49,152,000 B; a higher one, or a
    pool that is off, is left alone."""
    calls = _pool(monkeypatch, 1 << 20)
    S._keep_tape_memory("cuda:0", 1000)
    assert calls == [49_152_000]
    calls = _pool(monkeypatch, 1 << 30)
    S._keep_tape_memory("cuda:0", 1000)
    assert calls == []
    calls = _pool(monkeypatch, 0, enabled=False)
    S._keep_tape_memory("cuda:0", 1000)
    assert calls == []


def test_gc_is_paused_inside_and_restored_after_even_on_error():
    """_gc_paused: collection is off inside, back on after (also when the body raises), and stays off after
    if it was off before."""
    assert gc.isenabled()
    with S._gc_paused():
        assert not gc.isenabled()
    assert gc.isenabled()
    with pytest.raises(RuntimeError):
        with S._gc_paused():
            raise RuntimeError("frame failed")
    assert gc.isenabled()
    gc.disable()
    try:
        with S._gc_paused():
            pass
        assert not gc.isenabled()
    finally:
        gc.enable()
