"""Small render-sim runs for the tests of how variants are scheduled (in turn, in threads, on several devices)."""

import json


def tiny_bread(frames: int = 14):
    """The bread at 2,500 particles, 64×48 pixels, the torch renderer: its stress event latches near frame 9."""
    from fracture_gs.io.config import load_config

    cfg = load_config("bread")
    cfg.particles, cfg.frames, cfg.render.width, cfg.render.height = 2500, frames, 64, 48
    cfg.render.backend = "torch"
    return cfg


def metrics_rows(out_dir) -> dict:
    """metrics.jsonl by variant, each row without its variant and wall-clock fields."""
    out = {}
    for line in (out_dir / "metrics.jsonl").read_text().splitlines():
        r = json.loads(line)
        r.pop("wall", None)
        out.setdefault(r.pop("variant"), []).append(r)
    return out
