"""`render-sim --devices cuda:0,cuda:1,...`: the variants of one comparison side by side on several
devices of one machine, one thread per device (Warp and torch release the GIL in their kernels).

The first variant that runs an event provider leads: it runs on the first device, and what it
latches is handed to the others as it happens (`sim.providers.broadcast`), so every variant still
uses the one topology the leader found — the same contract as the sequential run, where the others
replay the leader's saved history. Variants beyond the number of devices queue on them in order.
Ctrl-C stops every variant at its next frame; an error in one thread stops the others and is
raised here.
"""

from __future__ import annotations

import threading
from pathlib import Path

from .sim.providers import make_provider
from .sim.providers.broadcast import BroadcastProvider, LeaderProvider, TopologyChannel


def run_on_devices(run_variant, cfg, gs_on, painters, order: list, devices: list, out_dir: Path, metrics_file, export):
    """Run `order` (leader first) over `devices` (one worker thread per entry; an entry may repeat).
    gs_on: device → Gaussians; painters: one Painter per entry of `devices` (a painter keeps per-run
    state). Returns (frames, summaries, leader history or None, interrupted)."""
    channel = TopologyChannel()
    stop = threading.Event()
    frames = {v: [] for v in order}
    summaries, errors, topology = {}, [], {"history": None}
    queues = [[] for _ in devices]
    for i, v in enumerate(order):
        queues[i % len(devices)].append(v)
    leader = order[0]
    lock = threading.Lock()

    def work(slot: int, variants: list) -> None:
        device = devices[slot]
        for variant in variants:
            if stop.is_set():
                return
            if variant == leader:
                provider = LeaderProvider(make_provider(cfg.topology), channel)
            else:
                provider = BroadcastProvider(channel)
            try:
                summary, history = run_variant(
                    cfg,
                    gs_on[device],
                    variant,
                    device,
                    out_dir,
                    painters[slot],
                    None,
                    metrics_file,
                    frames[variant],
                    export,
                    provider=provider,
                    stop=stop,
                    position=slot,
                )
            except BaseException as exc:  # noqa: BLE001 - handed to the caller
                with lock:
                    errors.append(exc)
                stop.set()
                channel.close()
                return
            finally:
                if variant == leader:
                    channel.close()  # followers past the leader's last frame stop waiting
            with lock:
                summaries[variant] = summary
                if variant == leader and history:
                    topology["history"] = history
            if summary.get("interrupted"):
                stop.set()

    threads = [
        threading.Thread(target=work, args=(i, vs), name=f"fgs-{devices[i]}-{i}", daemon=True)
        for i, vs in enumerate(queues)
        if vs
    ]
    for t in threads:
        t.start()
    interrupted = False
    try:
        for t in threads:
            while t.is_alive():
                t.join(timeout=0.2)
    except KeyboardInterrupt:
        interrupted = True
        stop.set()
        for t in threads:
            t.join()
    if errors:
        raise errors[0]
    interrupted = interrupted or any(s.get("interrupted") for s in summaries.values())
    return frames, summaries, topology["history"], interrupted
