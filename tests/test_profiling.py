"""The phase timer of `render-sim --profile` (`fracture_gs.profiling`): busy time per phase from any
thread, and no device-wide sync from any thread while another thread records a CUDA graph (such a sync
is a CUDA error; the renderer's thread ended a profiled GPU run that way)."""

import threading
import time

import torch

from fracture_gs.profiling import PhaseTimer


def test_sections_charge_their_own_phase_from_any_thread():
    """A nested section is charged to itself only (the outer one gets its own time less the inner's), and busy
    times of one phase on two threads add up. The sleeps are timed here too: a loaded machine wakes them late."""
    t = PhaseTimer()
    t.enable()
    t0 = time.perf_counter()
    with t.section("simulate"):
        time.sleep(0.05)
        t1 = time.perf_counter()
        with t.section("diagnostics"):  # nested: charged to itself only
            time.sleep(0.05)
        t2 = time.perf_counter()
    t3 = time.perf_counter()

    def render():
        with t.section("render"):
            time.sleep(0.05)

    worker = threading.Thread(target=render)
    worker.start()
    with t.section("render"):  # concurrently on this thread: busy times add up
        time.sleep(0.05)
    worker.join()
    inner, outer = t2 - t1, (t3 - t0) - (t2 - t1)
    assert 0.045 <= t.seconds["diagnostics"] <= inner + 0.005, (t.seconds, inner)
    # charged the inner section too, the outer would read at least outer + inner (≥ outer + 0.045)
    assert 0.045 <= t.seconds["simulate"] <= outer + 0.005, (t.seconds, outer)
    assert t.seconds["render"] >= 0.095
    assert t.calls == {"simulate": 1, "diagnostics": 1, "render": 2}
    assert "| simulate |" in t.report()


def test_no_device_sync_while_another_thread_records_a_graph(monkeypatch):
    """A thread inside `capturing()` holds off every other thread's section-boundary sync until the capture
    ends; a section syncs only the calling thread's current stream, never the whole device (which would
    make the renderer wait for the solver's queued substeps); with profiling off, `capturing()` costs
    nothing and takes no lock."""
    events = []

    class Stream:
        def synchronize(self):
            events.append(("sync", time.perf_counter()))

    monkeypatch.setattr(torch.cuda, "current_stream", lambda device=None: Stream())
    monkeypatch.setattr(torch.cuda, "synchronize", lambda device=None: events.append(("device sync", 0.0)))
    t = PhaseTimer()
    t.enable(sync_device="cuda:0")
    started = threading.Event()

    def capture():
        with t.capturing():
            started.set()
            time.sleep(0.2)
            events.append(("capture ended", time.perf_counter()))

    a = threading.Thread(target=capture)
    a.start()
    started.wait()
    with t.section("render"):  # syncs at entry and exit: both must wait for the capture
        pass
    a.join()
    names = [e[0] for e in events]
    assert names == ["capture ended", "sync", "sync"], names
    off = PhaseTimer()
    with off.capturing():
        assert off._device.acquire(blocking=False)  # not held
        off._device.release()
