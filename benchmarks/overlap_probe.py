"""What keeps the warm GPU main job's threads from overlapping: the job under one change at a time (issue 36).

Each mode runs `render-sim bread --preset paper` in a process of its own (settings that CUDA reads at start-up need
one) and times `main()` there, after the imports. The modes change how the run executes, never what it computes:

    base        as shipped
    noprio      every stream at torch's default priority (the solver's run at the highest: `runtime.stream_priority`)
    conn        CUDA_DEVICE_MAX_CONNECTIONS=32 (more hardware queues: streams stop sharing them)
    novrec      --no-view-record (the viewer's record off)
    norender    the painter draws once and hands that image back after, with --no-view-record: the solver alone
    nosurface   the surface measure answers "nothing behind another piece" without computing (its share)
    bare        norender and nosurface together: the solver with the rest of its diagnostics
    syncs       one run with torch's sync debug mode: every synchronising torch call counted by thread and site

    python benchmarks/overlap_probe.py [--rounds 2] [--device cuda:0] [--out-root /tmp] [MODE ...]
    python benchmarks/overlap_probe.py --device cpu --job "bread --frames 4" --rounds 1 base norender
"""

from __future__ import annotations

import argparse
import collections
import os
import subprocess
import sys
import time
import traceback

MODES = ("base", "noprio", "conn", "novrec", "norender", "nosurface", "bare")


def patch(mode: str) -> list[str]:
    """Apply `mode`'s change in this process; returns the extra command-line flags."""
    if mode == "noprio":  # every stream at torch's default priority, as before `runtime.stream_priority`
        from fracture_gs import runtime

        runtime.stream_priority = lambda purpose: 0  # `side_stream` looks it up at each new stream
    if mode in ("novrec", "norender", "bare"):
        extra = ["--no-view-record"]
    else:
        extra = []
    if mode in ("norender", "bare"):
        from fracture_gs.render_sim.painter import Painter

        draw = Painter.draw

        def once(self, out):
            if getattr(self, "_probe_image", None) is None:
                self._probe_image = draw(self, out)
            return self._probe_image

        Painter.draw = once
    if mode in ("nosurface", "bare"):
        from fracture_gs.sim.diagnostics.tracker import Diagnostics

        Diagnostics._surface = lambda self: {"depth": 0.0, "crossing": 0, "pairs": {}, "radius": 0.0}
    return extra


class SyncSites:
    """Counts torch's synchronising calls by (thread, innermost fracture_gs frame)."""

    def __init__(self):
        self.count = collections.Counter()

    def __call__(self, message, category, filename, lineno, file=None, line=None):
        import threading

        site = "?"
        for fs in reversed(traceback.extract_stack()[:-1]):
            if "fracture_gs" in fs.filename:
                site = f"{fs.filename.split('fracture_gs/')[-1]}:{fs.lineno} {fs.name}"
                break
        self.count[(threading.current_thread().name, site)] += 1


def child(mode: str, device: str, out: str, job: list[str]) -> int:
    import torch  # noqa: F401 - the imports before the clock starts

    import fracture_gs.cli.run  # noqa: F401
    from fracture_gs.cli import main

    extra = patch(mode if mode != "syncs" else "base")
    argv = ["render-sim", *job, "--device", device, "--out", out, *extra]
    sites = None
    if mode == "syncs":
        import warnings

        sites = SyncSites()
        warnings.simplefilter("always")
        warnings.showwarning = sites
        torch.cuda.set_sync_debug_mode("warn")
    t0 = time.perf_counter()
    rc = main(argv)
    wall = time.perf_counter() - t0
    print(f"PROBE {mode} {wall:.3f} {rc}", flush=True)
    if sites is not None:
        torch.cuda.set_sync_debug_mode(0)
        total = sum(sites.count.values())
        print(f"SYNCS total {total}")
        for (thread, site), n in sites.count.most_common(40):
            print(f"SYNCS {n:6d} {thread:14s} {site}")
    return rc


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--device", default="cuda:0")
    ap.add_argument("--job", default="bread --preset paper", help="the render-sim arguments before --device")
    ap.add_argument("--out-root", default="/tmp", help="each mode writes its run to OUT_ROOT/probe_MODE")
    ap.add_argument("--child", help=argparse.SUPPRESS)
    ap.add_argument("modes", nargs="*", default=list(MODES))
    a = ap.parse_args()
    job = a.job.split()
    if a.child:
        return child(a.child, a.device, os.path.join(a.out_root, f"probe_{a.child}"), job)
    walls: dict = collections.defaultdict(list)

    def run(mode: str) -> list[str]:
        env = dict(os.environ)
        if mode == "conn":
            env["CUDA_DEVICE_MAX_CONNECTIONS"] = "32"
        cmd = [
            sys.executable,
            __file__,
            "--device",
            a.device,
            "--job",
            a.job,
            "--out-root",
            a.out_root,
            "--child",
            mode,
        ]
        t0 = time.perf_counter()
        p = subprocess.run(cmd, env=env, capture_output=True, text=True)
        lines = [ln for ln in p.stdout.splitlines() if ln.startswith(("PROBE", "SYNCS"))]
        if p.returncode != 0 or not lines:
            print(f"{mode}: rc {p.returncode}\n{p.stderr[-2000:]}")
            return []
        walls[mode].append((float(lines[0].split()[2]), time.perf_counter() - t0))
        return lines

    modes = [m for m in a.modes if m != "syncs"]
    run("base")  # a warm-up: caches, and gsplat's build if it is missing
    walls.clear()
    if "syncs" in a.modes:
        for ln in run("syncs")[1:]:
            print(ln)
    for _ in range(a.rounds):
        for mode in modes:
            run(mode)
    print("\n| mode | main() s | process s |\n|---|---|---|")
    for mode, pairs in walls.items():
        print(f"| {mode} | {' / '.join(f'{w:.2f}' for w, _ in pairs)} | {' / '.join(f'{p:.1f}' for _, p in pairs)} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
