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


def assert_same_run(a_dir, b_dir, variants) -> None:
    """Two runs of one scene agree: every variant's per-frame metrics, and the latched topology history (frames,
    fragment and band labels), exactly; the stress event latched in them."""
    import torch

    from fracture_gs.sim.topology import load_history

    a, b = metrics_rows(a_dir), metrics_rows(b_dir)
    assert set(a) == set(b) == set(variants)
    assert any(r.get("latched") for r in a["full"]), "the stress event latched in this run"
    for v in variants:
        assert a[v] == b[v], v
    ha, hb = load_history(a_dir / "topology.npz"), load_history(b_dir / "topology.npz")
    assert len(ha) == len(hb) >= 1
    for ta, tb in zip(ha, hb):
        assert ta.latch_frame == tb.latch_frame
        assert torch.equal(ta.fragment, tb.fragment) and torch.equal(ta.band, tb.band)
