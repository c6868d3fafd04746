"""`render-sim --devices`: variants side by side on several devices, the leader's topology handed to
the others as it latches. On the CPU two worker threads stand in for two GPUs: every variant's
per-frame metrics and its latched topology equal those of the sequential run (bitwise, since the
CPU kernels are deterministic)."""

import json

import pytest
import torch

from fracture_gs import cli, runner
from fracture_gs.io.config import load_config
from fracture_gs.sim.providers.broadcast import TopologyChannel
from fracture_gs.sim.topology import load_history

pytestmark = pytest.mark.usefixtures("one_thread")


def tiny():
    cfg = load_config("bread")
    cfg.particles, cfg.frames, cfg.render.width, cfg.render.height = 2500, 14, 64, 48
    cfg.render.backend = "torch"
    return cfg


def rows(path):
    out = {}
    for line in (path / "metrics.jsonl").read_text().splitlines():
        r = json.loads(line)
        out.setdefault(r.pop("variant"), []).append(r)
    return out


def test_two_workers_match_the_sequential_run(tmp_path):
    variants = ["stress_zero", "full", "baseline"]
    runner.run_render_sim(tiny(), variants, "cpu", tmp_path / "seq")
    runner.run_render_sim(tiny(), variants, "cpu", tmp_path / "par", devices=["cpu", "cpu"])
    a, b = rows(tmp_path / "seq"), rows(tmp_path / "par")
    assert set(a) == set(b) == set(variants)
    latched = [r for r in a["full"] if r.get("latched")]
    assert latched, "the stress event latched in this run"
    for v in variants:
        for ra, rb in zip(a[v], b[v]):
            ra.pop("wall", None), rb.pop("wall", None)
        assert a[v] == b[v], v
    ha, hb = load_history(tmp_path / "seq" / "topology.npz"), load_history(tmp_path / "par" / "topology.npz")
    assert len(ha) == len(hb) >= 1
    for ta, tb in zip(ha, hb):
        assert ta.latch_frame == tb.latch_frame
        assert torch.equal(ta.fragment, tb.fragment) and torch.equal(ta.band, tb.band)
    assert (tmp_path / "par" / "comparison.mp4").exists()
    s = json.loads((tmp_path / "par" / "summary.json").read_text())
    assert [v["status"] for v in s["variants"]] == ["ok"] * 3


def test_channel_waits_for_the_leader_and_stops_when_it_closes():
    ch = TopologyChannel(timeout=0.2)
    ch.publish(0, None)
    assert ch.up_to(0) == []
    with pytest.raises(TimeoutError):
        ch.up_to(3)
    ch.close()
    assert ch.up_to(3) == []


def test_devices_flag_errors_are_one_line(capsys):
    assert cli.main(["render-sim", "bread", "--devices", "cuda:0,cuda:1"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "CUDA is not available" in err
    assert cli.main(["render-sim", "bread", "--devices", ","]) == 2
    assert "names no device" in capsys.readouterr().err
