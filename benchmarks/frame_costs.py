"""Where one variant's frame goes: each part of a render-sim frame timed alone and its torch ops counted.

A GPU frame of the main job is host-bound: each torch op is a launch (a few µs of Python and driver), each host
read waits for the queue. This runs one variant of a scene, and on every frame after the first latch times each
part of the frame on its own (synchronised before and after) and counts the torch ops it dispatches
(`TorchDispatchMode`) — the solver's frame, each diagnostic, the painter, the view record — then prints a table
(median ms a frame, ops a frame). On the CPU with a small scene the op counts are the same and the times rank the
parts by host cost.

    python benchmarks/frame_costs.py --device cuda:0 --preset paper --frames 40
    python benchmarks/frame_costs.py --device cpu --particles 3000 --frames 20
"""

from __future__ import annotations

import argparse
import collections
import functools
import pathlib
import statistics
import tempfile
import time

import torch
from torch.utils._python_dispatch import TorchDispatchMode

from fracture_gs.io.config import apply_overrides, load_config
from fracture_gs.pipeline import make_simulator, prepare_scene, simulate
from fracture_gs.render_sim.painter import Painter
from fracture_gs.viewer.record import FrameRecorder, start_record


class _Ops(TorchDispatchMode):
    """Counts the aten ops dispatched inside it."""

    def __init__(self):
        super().__init__()
        self.count = collections.Counter()

    def __torch_dispatch__(self, func, types, args=(), kwargs=None):
        self.count[func.overloadpacket.__name__] += 1
        return func(*args, **(kwargs or {}))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scene", default="bread")
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--preset", default=None)
    ap.add_argument("--particles", type=int, default=None)
    ap.add_argument("--frames", type=int, default=30)
    ap.add_argument("--variant", default="full")
    a = ap.parse_args()
    cfg = load_config(a.scene)
    cfg = apply_overrides(cfg, preset=a.preset, frames=a.frames, keys={"particles": a.particles})
    cuda = a.device.startswith("cuda")

    def sync():
        if cuda:
            torch.cuda.synchronize()

    scene = prepare_scene(cfg, a.device)
    gs = scene.gaussians
    painter = Painter(gs, cfg, a.device, scene.background).for_variant()
    view = start_record(pathlib.Path(tempfile.mkdtemp()), cfg, gs, scene.background, [a.variant])
    recorder = FrameRecorder(view, a.variant)
    sim = make_simulator(cfg, gs, a.variant, a.device)
    tracker = sim.diagnostics_tracker()
    times: dict = collections.defaultdict(list)
    ops: dict = {}

    def part(name: str, fn, count: bool):
        sync()
        t = time.perf_counter()
        r = fn()
        host = time.perf_counter() - t
        sync()
        times[name].append((host, time.perf_counter() - t))
        if count and name not in ops:
            c = _Ops()
            with c:
                fn()
            sync()
            ops[name] = c.count
        return r

    frames = simulate(sim, painter.cov0, cfg.frames, cfg.frame_dt, carrier=gs.carrier,
                      crack_faces=cfg.render.trim_cracks, max_stretch=cfg.render.max_stretch)  # fmt: skip
    out = part("frame 0 (set-up)", lambda: next(frames), False)
    latch = None
    while True:
        try:
            out = part("solver frame (incl. diagnostics)", lambda: next(frames), False)
        except StopIteration:
            break
        if sim.latched and latch is None:
            latch = out.frame
        counting = latch is not None and out.frame > latch + 2
        if latch is None or out.frame <= latch:
            continue
        part("  diagnostics: snapshot, all", tracker.snapshot, counting)
        part("  diagnostics: surface penetration", tracker._surface, counting)
        part("  diagnostics: particle numbers", tracker._particle_numbers, counting)
        part("paint (draw + host copy)", functools.partial(painter, out), counting)
        rgb, drawn = part("view colours", functools.partial(painter.view_colors, out), counting)
        part("view record write", functools.partial(recorder.write, out, rgb, drawn), counting)
    recorder.close()
    n = len(sim.particles)
    print(f"\n{a.scene} {a.preset or ''} {n} particles on {a.device}, variant {a.variant}, latched at frame {latch}")
    print("| part | frames | host ms (median) | wall ms (median) | ops a frame | top ops |")
    print("|---|---:|---:|---:|---:|---|")
    for name, rows in times.items():
        host = statistics.median(r[0] for r in rows) * 1e3
        wall = statistics.median(r[1] for r in rows) * 1e3
        c = ops.get(name)
        top = ", ".join(f"{k} {v}" for k, v in c.most_common(6)) if c else ""
        print(f"| {name} | {len(rows)} | {host:.2f} | {wall:.2f} | {sum(c.values()) if c else ''} | {top} |")


if __name__ == "__main__":
    main()
