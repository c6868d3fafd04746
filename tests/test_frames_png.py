"""`render-sim --frames-png / --no-frames-png`: the comparison frames as frames/compare_NNNN.png are optional, on by
default on the CPU (where they cost about 1 % of the run) and off on CUDA; a run without them leaves no PNG of an
earlier run behind and says that it wrote none."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from fracture_gs import cli
from fracture_gs import render_sim as runner
from fracture_gs.config import SceneConfig
from fracture_gs.io.video import read_video
from fracture_gs.render_sim import RunSummary
from fracture_gs.render_sim.comparison import compose_comparison, frames_png_default


def lists(n: int = 4):
    rng = np.random.default_rng(2)
    return [[rng.integers(0, 256, (24, 32, 3), dtype=np.uint8) for _ in range(n)] for _ in range(2)]


def test_the_pngs_are_the_comparison_frames_and_only_when_asked(tmp_path):
    """With PNGs on, frames/ holds one PNG per comparison frame (what the video was made from); with them off the
    video is the same length and frames/ does not exist, and PNGs an earlier run left in that folder are gone (a
    reader must not take them for this run's)."""
    cfg = SceneConfig(name="t", frame_dt=0.01)
    compose_comparison(cfg, ["a", "b"], lists(), None, tmp_path / "on", frames_png=True)
    pngs = sorted((tmp_path / "on" / "frames").glob("compare_*.png"))
    assert [p.name for p in pngs] == [f"compare_{i:04d}.png" for i in range(4)]
    assert cv2.imread(str(pngs[0])).shape[1] > 2 * 32, "a PNG is the side-by-side frame, not a panel"

    stale = tmp_path / "off" / "frames"
    stale.mkdir(parents=True)
    for i in range(6):
        cv2.imwrite(str(stale / f"compare_{i:04d}.png"), np.zeros((4, 4, 3), np.uint8))
    compose_comparison(cfg, ["a", "b"], lists(), None, tmp_path / "off", frames_png=False)
    assert not stale.exists()
    assert read_video(tmp_path / "off" / "comparison.mp4")[0] == read_video(tmp_path / "on" / "comparison.mp4")[0] == 4


def test_a_folder_holding_more_than_old_pngs_is_kept(tmp_path):
    """Only our own compare_NNNN.png files are removed: a file of the user's in frames/ stays, and the folder."""
    keep = tmp_path / "frames" / "notes.txt"
    keep.parent.mkdir()
    keep.write_text("mine")
    cv2.imwrite(str(tmp_path / "frames" / "compare_0000.png"), np.zeros((4, 4, 3), np.uint8))
    compose_comparison(SceneConfig(name="t", frame_dt=0.01), ["a", "b"], lists(2), None, tmp_path, frames_png=False)
    assert sorted(p.name for p in keep.parent.iterdir()) == ["notes.txt"]


def test_the_default_is_on_for_the_cpu_and_off_for_cuda():
    """The decision of docs/DESIGN.md ("Composing the comparison"): PNGs by default where they are cheap (the CPU
    run takes tens of seconds), not on CUDA (a run of a few seconds); --devices runs count as CUDA ones."""
    assert frames_png_default("cpu") is True
    assert frames_png_default("cuda:0") is False and frames_png_default("cuda") is False


@pytest.mark.parametrize(
    "flags, passed, says",
    [
        ([], None, "frames/, "),
        (["--frames-png"], True, "frames/, "),
        (["--no-frames-png"], False, "no frames/ PNGs (--frames-png writes them)"),
    ],
)
def test_the_flag_reaches_the_run_and_the_last_line_says_what_was_written(
    monkeypatch, tmp_path, capsys, flags, passed, says
):
    """--frames-png / --no-frames-png reach `run_render_sim` as frames_png (not given: the run's default, by
    device), and the outputs line lists frames/ only when the PNGs were written, else says how to get them."""
    calls = {}

    def fake_run(cfg, variants, device, out_dir, profile=False, stop=None, **kw):
        calls.update(kw)
        return RunSummary("bread", "bread", "small", device, 10, [], 3, 0.01, out_dir=str(out_dir))

    monkeypatch.setattr(runner, "run_render_sim", fake_run)
    argv = ["render-sim", "bread", "--frames", "3", "--device", "cpu", "--out", str(tmp_path), *flags]
    assert cli.main(argv) == 0
    assert calls.get("frames_png") is passed
    out = capsys.readouterr().out
    assert says in out and ("frames/, " in out) == (passed is not False)


@pytest.mark.slow
def test_render_sim_in_process_without_and_with_pngs(tmp_path, capsys):
    """The whole job on a tiny bread on the CPU: --no-frames-png writes the comparison video and no frames/;
    the CPU's default writes one PNG per comparison frame."""
    tiny = ["--particles", "1500", "--frames", "3", "--resolution", "64x48", "--device", "cpu", "--no-view-record"]
    assert (
        cli.main(
            [
                "render-sim",
                "bread",
                "--variants",
                "full,baseline",
                *tiny,
                "--out",
                str(tmp_path / "a"),
                "--no-frames-png",
            ]
        )
        == 0
    )
    assert read_video(tmp_path / "a" / "comparison.mp4")[0] == 4 and not (tmp_path / "a" / "frames").exists()
    assert "no frames/ PNGs" in capsys.readouterr().out
    assert cli.main(["render-sim", "bread", "--variants", "full,baseline", *tiny, "--out", str(tmp_path / "b")]) == 0
    assert len(list((tmp_path / "b" / "frames").glob("compare_*.png"))) == 4
