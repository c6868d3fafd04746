"""Regenerate every table and figure of the paper (thin wrapper; the logic is `fracture_gs.figures`).

    python apps/make_figures.py                          # CPU: quick preset, a few minutes
    python apps/make_figures.py --device cuda:0          # GPU: paper preset (Δx = 1/128, paper particle counts)
    python apps/make_figures.py --device cuda:0 --only ficus --out figures/gpu     # split a long GPU job ...
    python apps/make_figures.py --device cuda:0 --only bread,interaction,bench --reuse --out figures/gpu

`fracture-gs figures [--device D] [--out DIR]` calls `run_figures(device, out_dir)` (quick on the
CPU, paper on CUDA). Outputs: tables/*.md|csv|tex, fig_*.png, data/*.json, README.md.
"""
from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from fracture_gs.figures import main, run_figures  # noqa: E402,F401

if __name__ == "__main__":
    sys.exit(main())
