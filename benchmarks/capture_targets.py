"""Real captures against the "breaks like the real thing" targets, each run as a user runs it.

For every capture file and load it runs, as a separate process timed from the shell,

    fracture-gs render-sim FILE --device DEVICE --frames 40 [--load LOAD] --out OUT/NAME_LOAD

and reads back what the user gets: the wall time, whether `full` broke into ≥ 2 pieces of ≥ 3 % of the
particles each (`topology.npz`) and separated (`summary.json`), and the edge strength of `full.mp4`'s last
frame against its first (`capture.quality.edge_strength`). A table goes to stdout and OUT/targets.md.

    python benchmarks/capture_targets.py tests/data/captures/guitar.compressed.ply /path/to/seal.splat --loads auto,drop
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

import imageio.v2 as imageio
import numpy as np

from fracture_gs.capture.quality import edge_strength, pieces

TARGET_SECONDS = 300.0
TARGET_EDGE = 0.9


def apart(full: dict) -> bool:
    """The pieces separated: the first interface opened (`separated`), or the two largest pieces are more than
    half a cell apart at the end (`piece_gap`: a shatter can push the first crack shut while the pieces fly)."""
    return full.get("separated") in (True, "yes") or full.get("piece_gap", 0.0) > 0.5


def run_one(path: Path, load: str, device: str, frames: int, out: Path) -> dict:
    folder = out / f"{path.name.replace('.', '_')}_{load}"
    exe = Path(sys.executable).with_name("fracture-gs")  # the console script a user runs, from this environment
    cli = [str(exe)] if exe.exists() else [sys.executable, "-m", "fracture_gs.cli"]
    cmd = [*cli, "render-sim", str(path), "--device", device, "--frames", str(frames), "--out", str(folder)]
    if load != "auto":
        cmd += ["--load", load]
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    row = {"file": path.name, "load": load, "wall_s": round(wall, 1), "rc": proc.returncode}
    if proc.returncode != 0:
        row["error"] = (proc.stderr.strip().splitlines() or ["?"])[-1]
        return row
    summary = json.loads((folder / "summary.json").read_text())
    full = next(v for v in summary["variants"] if v["variant"] == "full")
    big = []  # no topology.npz: nothing latched, nothing broke
    if (folder / "topology.npz").exists():
        with np.load(folder / "topology.npz") as z:
            big = pieces(z["fragment"])
    video = imageio.get_reader(folder / "full.mp4")
    first, last = video.get_data(0), None
    for frame in video:  # to the last frame (an MP4's frame count in its metadata is unreliable)
        last = frame
    e0, e1 = edge_strength(first), edge_strength(last)
    notes = summary.get("capture", [])
    row.update(
        chosen=next((n for n in notes if n.startswith("load")), ""),
        particles=summary.get("particles"),
        pieces=len(big),
        shares=[round(c / sum(big), 2) for c in big][:6],
        separated=full.get("separated"),
        gap=round(full.get("piece_gap", 0.0), 2),
        edge=round(e1 / max(e0, 1e-12), 3),
        ok=bool(wall <= TARGET_SECONDS and len(big) >= 2 and apart(full)) and e1 >= TARGET_EDGE * e0,
    )
    return row


def verdict(row: dict) -> str:
    return "yes" if row.get("ok") else "no: " + row.get("error", "target missed")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("files", nargs="+", type=Path, help="capture files in their shipped formats")
    ap.add_argument("--loads", default="auto,drop", help="comma-separated loads (auto: the capture's default)")
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--frames", type=int, default=40)
    ap.add_argument("--out", type=Path, default=Path("runs/capture_targets"))
    args = ap.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    rows = []
    for f in args.files:
        for load in args.loads.split(","):
            row = run_one(f, load.strip(), args.device, args.frames, args.out)
            print(json.dumps(row), flush=True)
            rows.append(row)
    head = "| file | load | wall s | pieces ≥ 3 % | separated | gap of the 2 largest / Δx | edge last/first | ok |\n"
    head += "|---|---|---:|---:|---|---:|---:|---|\n"
    body = "".join(
        f"| {r['file']} | {r['load']} | {r['wall_s']} | {r.get('pieces', '-')} | {r.get('separated', '-')} | "
        f"{r.get('gap', '-')} | {r.get('edge', '-')} | {verdict(r)} |\n"
        for r in rows
    )
    (args.out / "targets.md").write_text(head + body)
    print(head + body)
    return 0 if all(r.get("ok") for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
