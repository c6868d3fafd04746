"""The phase timer of `render-sim --profile` (`fracture_gs.profiling`): busy time per phase from any
thread, and no device-wide sync from any thread while another thread records a CUDA graph (such a sync
is a CUDA error; the renderer's thread ended a profiled GPU run that way), while the threads' own stream
syncs never wait for each other (a profiled run must not serialise what the unprofiled run overlaps)."""

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
        assert _idle(off)  # nothing taken


def _idle(timer: PhaseTimer) -> bool:
    """No sync under way or waiting and no recording in the timer's gate."""
    gate = timer._gate
    return gate._owner is None and not gate._syncs and not gate._waiting


class _SlowStream:
    """A stand-in for torch's current stream whose sync takes `seconds` and notes (thread, start, end)."""

    def __init__(self, log: list, seconds: float):
        self.log, self.seconds = log, seconds

    def synchronize(self):
        start = time.perf_counter()
        time.sleep(self.seconds)
        self.log.append((threading.current_thread().name, start, time.perf_counter()))


def test_two_threads_syncs_overlap(monkeypatch):
    """Profiled, the solver's thread and the renderer's each wait for their own stream at every section boundary;
    those waits run side by side (one lock around every sync made each thread wait out the other's stream, so a
    profiled GPU run was slower than the run it measures by more than its own syncs)."""
    log = []
    monkeypatch.setattr(torch.cuda, "current_stream", lambda device=None: _SlowStream(log, 0.15))
    t = PhaseTimer()
    t.enable(sync_device="cuda:0")
    both = threading.Barrier(2)

    def work(name):
        both.wait()
        with t.section(name):
            pass

    threads = [threading.Thread(target=work, args=(n,), name=n) for n in ("simulate", "render")]
    for th in threads:
        th.start()
    for th in threads:
        th.join()
    assert sorted({name for name, _, _ in log}) == ["render", "simulate"] and len(log) == 4
    solver = [(a, b) for name, a, b in log if name == "simulate"]
    render = [(a, b) for name, a, b in log if name == "render"]
    assert any(a1 < b2 and a2 < b1 for a1, b1 in solver for a2, b2 in render), log  # some waits at once


def test_a_recording_waits_for_the_syncs_under_way_and_holds_off_new_ones(monkeypatch):
    """A thread that starts recording while another thread's sync is under way waits for that sync to end (the
    sync would otherwise run during the capture); syncs that come while it records wait for its end; the recording
    thread's own sections still sync (they wait for its own stream, not another's recording)."""
    log = []
    monkeypatch.setattr(torch.cuda, "current_stream", lambda device=None: _SlowStream(log, 0.2))
    t = PhaseTimer()
    t.enable(sync_device="cuda:0")
    window = []
    in_sync = threading.Event()

    def render():
        with t.section("render"):  # its entry sync is under way when the recording asks
            in_sync.set()

    def record():
        assert in_sync.wait(5)
        with t.capturing():
            window.append(time.perf_counter())
            with t.section("simulate"):  # the recording thread's own section: it syncs, without deadlock
                pass
            window.append(time.perf_counter())

    a = threading.Thread(target=render, name="render")
    a.start()
    time.sleep(0.05)  # the render thread is inside its first sync
    b = threading.Thread(target=record, name="record")
    b.start()
    a.join(10), b.join(10)
    assert not a.is_alive() and not b.is_alive()
    begin, end = window
    first = min(start for name, start, _ in log if name == "render")
    assert any(name == "record" and begin <= s and e <= end for name, s, e in log), log  # its own syncs ran
    for name, s, e in log:  # no other thread's sync overlaps the recording
        if name == "render":
            assert e <= begin or s >= end, (log, window)
    assert first < begin  # the render thread's sync under way was waited for, not cut into
    assert _idle(t)
