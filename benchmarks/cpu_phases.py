"""CPU seconds per phase of the README's CPU job, one variant at a time with everything on this thread.

A render-sim run on a CPU spreads its work over processes and threads (the variants in forked workers, drawing on a
worker thread, torch's OpenMP pool), so wall times mix the phases and the host's load. This runs each variant's
frames in turn on one thread (torch on one thread, Warp's per-particle kernels unsplit) and charges the thread's
CPU time (`time.thread_time`, unaffected by other processes' load) to: the frame loop with its substeps, the
per-frame diagnostics snapshot, drawing the frame (`Painter`) and recording it for the viewer. Followers replay
the leader's topology, as the job does.

    PYTHONPATH=. python benchmarks/cpu_phases.py          # bread, its three variants, 90 frames
    PYTHONPATH=. python benchmarks/cpu_phases.py --variants full --frames 40

(`PYTHONPATH=.`: a script's folder, not the working directory, starts Python's path, so without it a checkout
other than the installed one would time the installed package.)
"""

from __future__ import annotations

import argparse
import tempfile
import time

import torch

from fracture_gs.io.config import load_config
from fracture_gs.pipeline import make_simulator, prepare_scene, simulate
from fracture_gs.render_sim.painter import Painter
from fracture_gs.runtime import share_cpu
from fracture_gs.sim.diagnostics import tracker
from fracture_gs.viewer.record import FrameRecorder, start_record


def run_variant(cfg, scene, variant: str, frames: int, topology, folder) -> tuple[dict, list]:
    """CPU seconds per phase of one variant, and the topology history it latched (or replayed)."""
    gs = scene.gaussians
    painter = Painter(gs, cfg, "cpu", background=scene.background).for_variant()
    view = start_record(folder, cfg, gs, scene.background, [variant])
    record = FrameRecorder(view, variant)
    sim = make_simulator(cfg, gs, variant, "cpu", topology=topology)
    seconds = {"frame loop and substeps": 0.0, "diagnostics": 0.0, "draw": 0.0, "view record": 0.0}
    snapshot = tracker.Diagnostics.snapshot

    def timed(self):
        t = time.thread_time()
        try:
            return snapshot(self)
        finally:
            seconds["diagnostics"] += time.thread_time() - t

    tracker.Diagnostics.snapshot = timed
    try:
        t0 = time.thread_time()
        for out in simulate(sim, painter.cov0, frames, cfg.frame_dt, carrier=gs.carrier):
            t = time.thread_time()
            painter(out)
            t1 = time.thread_time()
            record.write(out, *painter.view_colors(out))
            seconds["draw"] += t1 - t
            seconds["view record"] += time.thread_time() - t1
        total = time.thread_time() - t0
    finally:
        tracker.Diagnostics.snapshot = snapshot
        record.close()
    seconds["frame loop and substeps"] = total - sum(seconds.values())
    return seconds, list(sim.topologies)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default="bread")
    ap.add_argument("--variants", default=None, help="comma-separated (default: the config's, leader first)")
    ap.add_argument("--frames", type=int, default=None)
    args = ap.parse_args()
    torch.set_num_threads(1)
    share_cpu(1)
    cfg = load_config(args.scene)
    scene = prepare_scene(cfg, "cpu")
    cfg = scene.cfg
    variants = args.variants.split(",") if args.variants else sorted(cfg.variants, key=lambda v: v == "baseline")
    frames = args.frames or cfg.frames
    history, totals = None, {}
    with tempfile.TemporaryDirectory() as folder:
        for k, variant in enumerate(variants):
            seconds, latched = run_variant(cfg, scene, variant, frames, history, f"{folder}/{k}")
            history = history or latched or None
            print(f"{variant:>12}: " + ", ".join(f"{name} {s:.2f} s" for name, s in seconds.items()))
            for name, s in seconds.items():
                totals[name] = totals.get(name, 0.0) + s
    print(f"{'all':>12}: " + ", ".join(f"{name} {s:.2f} s" for name, s in totals.items()))


if __name__ == "__main__":
    main()
