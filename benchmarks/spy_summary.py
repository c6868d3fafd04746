"""Where a sampled run's threads spent their time: a summary of a `py-spy record --format raw` file.

A GPU frame of the main job is host-bound, and its threads (the solver's, the renderer's, the composer's) share one
interpreter lock, so the question is which Python code holds the lock and which waits for the device. Record the
run with py-spy, then summarise it per thread: the functions that include the most samples (inclusive, each counted
once per stack) and the innermost frames (self), in samples and in seconds at the sampling rate.

    py-spy record --threads --gil -r 200 --format raw -o gil.txt -- fracture-gs render-sim bread --preset paper ...
    python benchmarks/spy_summary.py gil.txt --rate 200 --top 25
    python benchmarks/spy_summary.py idle.txt --rate 200 --only fracture_gs   # innermost frames of the package only

(`--gil`: only samples of the thread holding the lock; `--idle` as well: every thread's every sample, waits too.)
"""

from __future__ import annotations

import argparse
import collections
import re
from typing import Iterable

FRAME = re.compile(r"^(?P<name>.*?) \((?P<file>[^()]*?)(?::(?P<line>\d+))?\)$")


def parse(lines: Iterable[str]) -> list[tuple[str, list[str], int]]:
    """(thread, frames outermost first, samples) of each line `thread (id): f (file:line);g (file:line) COUNT`;
    a frame is named `function (file)`, its line dropped, so one function's lines count together."""
    rows = []
    for line in lines:
        line = line.rstrip("\n")
        if not line.strip():
            continue
        stack, _, count = line.rpartition(" ")
        if not count.isdigit():
            continue
        parts = stack.split(";")
        thread = re.sub(r"^thread \(\w+\): ", "", parts[0])  # "thread (1234): MainThread" -> "MainThread"
        frames = []
        for p in parts[1:]:
            m = FRAME.match(p.strip())
            frames.append(f"{m['name']} ({m['file']})" if m else p.strip())
        rows.append((thread, frames, int(count)))
    return rows


def summarise(rows, only: str = "", top: int = 20) -> dict:
    """Per thread: total samples, the `top` inclusive and the `top` self frames. `only`: inclusive counts only frames
    whose name or file contains it, and the self frame is the innermost such frame (`(outside)` when none is)."""
    out = {}
    threads = sorted({t for t, _, _ in rows})
    for thread in threads:
        total, inclusive, inner = 0, collections.Counter(), collections.Counter()
        for t, frames, n in rows:
            if t != thread:
                continue
            total += n
            for f in set(frames):
                if only in f:
                    inclusive[f] += n
            picked = [f for f in frames if only in f] if only else frames
            inner[picked[-1] if picked else "(outside)"] += n
        out[thread] = {"samples": total, "inclusive": inclusive.most_common(top), "self": inner.most_common(top)}
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("raw", help="a `py-spy record --format raw` file")
    ap.add_argument("--rate", type=float, default=100.0, help="the recording's samples per second (py-spy -r)")
    ap.add_argument("--top", type=int, default=20)
    ap.add_argument("--only", default="", help="self frames: the innermost frame whose file contains this")
    ap.add_argument("--threads", default="", help="comma-separated thread names to print (default: all)")
    a = ap.parse_args()
    with open(a.raw) as f:
        table = summarise(parse(f), a.only, a.top)
    keep = set(a.threads.split(",")) if a.threads else None
    for thread, s in table.items():
        if keep is not None and thread not in keep:
            continue
        print(f"\n## {thread}: {s['samples']} samples = {s['samples'] / a.rate:.2f} s")
        for title in ("inclusive", "self"):
            print(f"| {title} | samples | s |\n|---|---:|---:|")
            for name, n in s[title]:
                print(f"| {name} | {n} | {n / a.rate:.2f} |")


if __name__ == "__main__":
    main()
