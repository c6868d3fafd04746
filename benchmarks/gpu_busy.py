"""How busy the GPU is during a run: CUDA kernel and copy time against the run's wall, from torch's CUPTI profiler.

A warm GPU main job is far slower than its kernels (issue 36), so the question is whether the device or the host
sets its pace. This runs one CLI command in this process under `torch.profiler` with CUDA activity only (no CPU
op tracing, which would slow the host), then prints the run's wall, the device's busy time (the union of every
kernel's and copy's interval, any stream), the summed kernel time, and the kernels and copies that take the most.

    python benchmarks/gpu_busy.py -- render-sim bread --preset paper --device cuda:0 --out /tmp/busy
"""

from __future__ import annotations

import argparse
import collections
import sys
import time


def busy_union(intervals: list[tuple[float, float]]) -> float:
    """Length of the union of [start, end) intervals (any order, overlaps counted once)."""
    total, end = 0.0, float("-inf")
    for a, b in sorted(intervals):
        if b <= end:
            continue
        total += b - max(a, end)
        end = b
    return total


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--top", type=int, default=25)
    ap.add_argument("command", nargs=argparse.REMAINDER, help="-- then a fracture-gs command line")
    a = ap.parse_args()
    argv = a.command[1:] if a.command[:1] == ["--"] else a.command
    import torch
    from torch.profiler import ProfilerActivity, profile

    if not torch.cuda.is_available():
        print("gpu_busy.py measures a CUDA device's busy time, and torch sees no CUDA device here", file=sys.stderr)
        return 2

    from fracture_gs.cli import main as cli

    t0 = time.perf_counter()
    with profile(activities=[ProfilerActivity.CUDA]) as prof:
        rc = cli(argv)
    wall = time.perf_counter() - t0
    torch.cuda.synchronize()
    spans, by_name = [], collections.defaultdict(lambda: [0.0, 0])
    for e in prof.events():
        if e.device_type != torch.autograd.DeviceType.CUDA:
            continue
        start, end = e.time_range.start, e.time_range.end  # µs
        spans.append((start, end))
        by_name[e.name][0] += end - start
        by_name[e.name][1] += 1
    busy = busy_union(spans) / 1e6
    summed = sum(t for t, _ in by_name.values()) / 1e6
    first, last = (min(s for s, _ in spans) / 1e6, max(e for _, e in spans) / 1e6) if spans else (0.0, 0.0)
    print(f"\nrc {rc}; the command's wall {wall:.2f} s; device activity from first to last {last - first:.2f} s")
    print(f"device busy (union of kernels and copies) {busy:.2f} s; summed {summed:.2f} s over {len(spans)} launches")
    print("| kernel or copy | total ms | calls | µs a call |\n|---|---:|---:|---:|")
    for name, (t, n) in sorted(by_name.items(), key=lambda kv: -kv[1][0])[: a.top]:
        print(f"| {name[:90]} | {t / 1e3:.1f} | {n} | {t / n:.1f} |")
    return rc or 0


if __name__ == "__main__":
    sys.exit(main())
