"""GPU soak (issue 18): render-sim and the Table 2 bench in a loop for a while on one GPU; after every
run the GPU memory held by torch must return to where it stood after the first run (no leak: the
first run may keep process-wide caches such as the shared stream's cuBLAS workspace, reported) and the
run's metrics must equal the first run's up to float32 atomic-order noise (same device, same inputs).

    python benchmarks/soak.py --device cuda:0 --minutes 10 --out runs/soak
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import torch

from fracture_gs.io.config import load_config
from fracture_gs.paper.bench import run_bench
from fracture_gs.render_sim import run_render_sim


def _metrics(out: Path) -> list:
    rows = [json.loads(line) for line in (out / "metrics.jsonl").read_text().splitlines()]
    for r in rows:
        r.pop("wall", None)
    return rows


def _close(a, b, rtol=1e-3, atol=1e-6) -> bool:
    """Equal up to the order of float32 atomic sums on the GPU: P2G adds in a varying order, so a node's
    mass can differ in its last bits and a thresholded count (e.g. shared_support_pct) by a node."""
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_close(a[k], b[k], rtol, atol) for k in a)
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(_close(x, y, rtol, atol) for x, y in zip(a, b))
    if isinstance(a, float) and isinstance(b, float):
        return abs(a - b) <= atol + rtol * max(abs(a), abs(b))
    return a == b


def _first_difference(a, b, path="") -> str:
    """Where two metric trees first differ beyond `_close` (for the log of a run that differs)."""
    if isinstance(a, dict) and isinstance(b, dict):
        for k in a:
            if k not in b or not _close(a[k], b[k]):
                return _first_difference(a[k], b.get(k), f"{path}.{k}")
    if isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
        for i, (x, y) in enumerate(zip(a, b)):
            if not _close(x, y):
                return _first_difference(x, y, f"{path}[{i}]")
    return f"{path}: {a!r} vs {b!r}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--device", default="cuda:0")
    ap.add_argument("--minutes", type=float, default=10.0)
    ap.add_argument("--iterations", type=int, default=0, help="stop after this many runs (0: only --minutes)")
    ap.add_argument("--frames", type=int, default=30)
    ap.add_argument("--particles", type=int, default=None, help="bread particle count (default: the small preset's)")
    ap.add_argument("--bench-particles", type=int, default=50_000, help="particles of the Table 2 bench per run")
    ap.add_argument("--out", default="runs/soak")
    args = ap.parse_args()
    out = Path(args.out)
    cfg = load_config("bread")
    cfg.frames, cfg.render.backend, cfg.particles = args.frames, "torch", args.particles
    cuda = args.device.startswith("cuda")
    sync = torch.cuda.synchronize if cuda else (lambda: None)
    held_now = (lambda: torch.cuda.memory_allocated(args.device)) if cuda else (lambda: 0)
    sync()
    first, rows, t_end, i, base, warm = None, [], time.time() + 60 * args.minutes, 0, held_now(), 0
    while time.time() < t_end and not (args.iterations and i >= args.iterations):
        t0 = time.time()
        run_render_sim(cfg, ["baseline", "full"], args.device, out / "run", progress=False)
        metrics = _metrics(out / "run")
        run_bench(
            device=args.device,
            out_dir=out / "bench",
            particles=args.bench_particles,
            steps=50,
            warmup=5,
            trials=1,
            placements=1,
        )
        sync()
        if i == 0:  # what the first run keeps for the process (cuBLAS workspace of the shared stream, ...)
            warm, base = held_now() - base, held_now()
        held = held_now() - base
        first = first if first is not None else metrics
        same = _close(metrics, first)
        rows.append({"run": i, "seconds": round(time.time() - t0, 1), "held_bytes": int(held), "same_metrics": same})
        if not same:
            rows[-1]["difference"] = _first_difference(first, metrics)[:300]
        print(json.dumps(rows[-1]), flush=True)
        i += 1
    summary = {
        "device": torch.cuda.get_device_name(args.device) if cuda else "cpu",
        "runs": len(rows),
        "kept_by_first_run_bytes": int(warm),
        "max_held_bytes": max(r["held_bytes"] for r in rows),
        "all_same_metrics": all(r["same_metrics"] for r in rows),
        "peak_bytes": torch.cuda.max_memory_allocated(args.device) if cuda else None,
    }
    (out / "soak.json").write_text(json.dumps({"summary": summary, "rows": rows}, indent=2))
    print(json.dumps(summary))
    if summary["max_held_bytes"] > 0 or not summary["all_same_metrics"]:
        raise SystemExit("soak failed: memory was left held after a run or a run's metrics differed from the first")


if __name__ == "__main__":
    main()
