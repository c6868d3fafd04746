"""How far two render-sim runs' metrics differ: the largest difference per metric over rows matched by variant and
frame (GPU atomics make two runs of one code differ, so a change is judged against that spread).

    python benchmarks/metrics_gap.py RUN_A RUN_B        # folders holding metrics.jsonl
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

KEYS = ("fragment_penetration", "fragment_crossing", "opening", "energy_total", "penetration", "identity_crossing")


def rows(folder) -> dict:
    """(variant, frame) → metrics row of a run's metrics.jsonl ({} when the run wrote none)."""
    path = Path(folder) / "metrics.jsonl"
    if not path.exists():
        return {}
    out = {}
    for line in path.read_text().splitlines():
        r = json.loads(line)
        out[(r.get("variant"), r.get("frame"))] = r
    return out


def gap(a: dict, b: dict) -> dict:
    """Largest |a − b| per metric over the rows both runs have (momentum: of its summed absolute components)."""
    worst: dict = {}
    for key in a.keys() & b.keys():
        x, y = a[key], b[key]
        pairs = [(k, x.get(k), y.get(k)) for k in KEYS]
        if isinstance(x.get("momentum"), list) and isinstance(y.get("momentum"), list):
            pairs.append(("momentum", sum(map(abs, x["momentum"])), sum(map(abs, y["momentum"]))))
        for k, u, v in pairs:
            if isinstance(u, (int, float)) and isinstance(v, (int, float)):
                worst[k] = max(worst.get(k, 0.0), abs(u - v))
    return {k: f"{v:.3g}" for k, v in sorted(worst.items())}


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    print(f"{sys.argv[1]} against {sys.argv[2]}:", gap(rows(sys.argv[1]), rows(sys.argv[2])))
