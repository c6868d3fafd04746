"""No output lost (issue 18, item 9): a variant that is interrupted or diverges gets a status row in
summary.json and summary.md ("interrupted at frame N", "diverged at frame N: cause"), holds its last
frame in comparison.mp4 with a caption saying why, and the CLI's last line states the cause. The variants
run in turn here (a later variant is "not run"); tests/test_variant_threads.py interrupts them in threads."""

import json
import os
import subprocess
import sys

import imageio.v2 as imageio
import pytest

from fracture_gs import pipeline
from fracture_gs import render_sim as runner
from fracture_gs.io.config import load_config
from fracture_gs.render_sim import variant as render_variant

pytestmark = pytest.mark.usefixtures("one_thread")


def tiny(frames=5):
    cfg = load_config("recontact")
    cfg.frames, cfg.render.width, cfg.render.height = frames, 96, 64
    cfg.render.backend = "torch"
    return cfg


@pytest.mark.slow
def test_interrupt_keeps_a_row_per_variant_and_the_held_frame(tmp_path, monkeypatch):
    cfg = tiny()
    real = pipeline.simulate
    calls = {"n": 0}

    def interrupted_second_variant(sim, cov0, frames, frame_dt, **kw):
        calls["n"] += 1
        for out in real(sim, cov0, frames, frame_dt, **kw):
            if calls["n"] == 2 and out.frame == 2:
                raise KeyboardInterrupt
            yield out

    monkeypatch.setattr(render_variant, "simulate", interrupted_second_variant)
    with pytest.raises(KeyboardInterrupt):
        runner.run_render_sim(cfg, ["full", "local_multifield"], "cpu", tmp_path, schedule="in_turn")
    summary = json.loads((tmp_path / "summary.json").read_text())
    status = {v["variant"]: v["status"] for v in summary["variants"]}
    assert status == {"full": "ok", "local_multifield": "interrupted at frame 1"}
    assert summary["interrupted"] is True
    md = (tmp_path / "summary.md").read_text()
    assert "interrupted at frame 1" in md
    reader = imageio.get_reader(str(tmp_path / "comparison.mp4"), "ffmpeg")
    assert reader.count_frames() == cfg.frames + 1, "the comparison runs to the longest variant, the other one held"


@pytest.mark.slow
def test_three_variants_interrupted_in_the_second(tmp_path, monkeypatch):
    cfg = tiny(3)
    real = pipeline.simulate
    calls = {"n": 0}

    def stop(sim, cov0, frames, frame_dt, **kw):
        calls["n"] += 1
        for out in real(sim, cov0, frames, frame_dt, **kw):
            if calls["n"] == 2 and out.frame == 1:
                raise KeyboardInterrupt
            yield out

    monkeypatch.setattr(render_variant, "simulate", stop)
    with pytest.raises(KeyboardInterrupt):
        runner.run_render_sim(cfg, ["full", "local_multifield", "stress_zero"], "cpu", tmp_path, schedule="in_turn")
    rows = json.loads((tmp_path / "summary.json").read_text())["variants"]
    assert [r["status"] for r in rows] == ["ok", "interrupted at frame 0", "not run (interrupted before it)"]


@pytest.mark.slow
def test_divergence_states_its_cause_in_every_output(tmp_path):
    cfg = tmp_path / "stiff.toml"
    cfg.write_text(
        'extends = "recontact"\nframes = 3\n[sim]\nadaptive_dt = false\ndt = 0.004\n'
        '[material]\nE = 5.0e7\n[render]\nwidth = 96\nheight = 64\nbackend = "torch"\n'
    )
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    res = subprocess.run(
        [
            sys.executable,
            "-m",
            "fracture_gs.cli",
            "render-sim",
            str(cfg),
            "--device",
            "cpu",
            "--out",
            str(tmp_path / "o"),
        ],
        capture_output=True,
        text=True,
        timeout=600,
        env=env,
    )
    assert res.returncode == 1
    last = res.stderr.strip().splitlines()[-1]
    assert last.startswith("fracture-gs: error:") and "diverged at frame" in last and "CFL bound" in last
    rows = json.loads((tmp_path / "o" / "summary.json").read_text())["variants"]
    assert all(r["status"].startswith("diverged at frame") and "CFL bound" in r["status"] for r in rows)
    assert "CFL bound" in (tmp_path / "o" / "summary.md").read_text()
