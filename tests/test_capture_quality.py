"""A real capture breaks like the real thing, run as a user runs it: the targets of captured objects on the
whole guitar (90,854 Gaussians, PlayCanvas compressed PLY, tests/data/captures), and the measures they use."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import imageio.v2 as imageio
import numpy as np
import pytest

from fracture_gs.capture.quality import edge_strength, pieces

GUITAR = Path(__file__).parent / "data" / "captures" / "guitar.compressed.ply"


def test_edge_strength_falls_with_blur_and_ignores_the_background():
    """A sharp checker disc on white has higher edge strength than the same disc blurred; the white around it
    does not count (doubling the canvas leaves the number unchanged)."""
    n = 64
    y, x = np.mgrid[:n, :n]
    disc = (x - n / 2) ** 2 + (y - n / 2) ** 2 < (n / 3) ** 2
    checker = ((x // 4 + y // 4) % 2).astype(float)
    img = np.ones((n, n, 3))
    img[disc] = (0.2 + 0.5 * checker[disc])[:, None]
    k = np.ones(5) / 5
    blur = img.copy()
    for axis in (0, 1):
        blur = np.apply_along_axis(lambda r: np.convolve(r, k, mode="same"), axis, blur)
    blur[~disc] = 1.0
    sharp, soft = edge_strength(img), edge_strength(blur)
    assert soft < 0.6 * sharp
    big = np.ones((2 * n, 2 * n, 3))
    big[n // 2 : n // 2 + n, n // 2 : n // 2 + n] = img
    assert edge_strength(big) == pytest.approx(sharp, rel=0.05)
    assert edge_strength(np.ones((8, 8, 3))) == 0.0


def test_pieces_count_only_fragments_of_the_share():
    """Fragments of 50 %, 40 %, 8 % and crumbs of 1 % each: three pieces of ≥ 3 %, largest first; the
    unlabelled (−1) particles count in the total but are no piece."""
    f = np.array([0] * 50 + [1] * 40 + [2] * 8 + [3] + [-1])
    assert pieces(f, 0.03) == [50, 40, 8]
    assert pieces(np.full(10, -1)) == []


@pytest.mark.slow
def test_a_real_capture_breaks_visibly_with_one_command(tmp_path):
    """`fracture-gs render-sim guitar.compressed.ply --device cpu --frames 40` with nothing else: the `full`
    variant breaks the guitar into ≥ 2 pieces of ≥ 3 % of the particles each, they separate (the first crack opens,
    or the two largest pieces end more than half a cell apart), and its video's last
    frame keeps ≥ 0.9 of frame 0's edge strength (nothing smeared or ghosted)."""
    out = tmp_path / "guitar"
    cmd = [sys.executable, "-m", "fracture_gs.cli", "render-sim", str(GUITAR), "--device", "cpu", "--frames", "40"]
    res = subprocess.run([*cmd, "--out", str(out)], capture_output=True, text=True, timeout=1200)
    assert res.returncode == 0, res.stderr[-3000:]
    summary = json.loads((out / "summary.json").read_text())
    full = next(v for v in summary["variants"] if v["variant"] == "full")
    with np.load(out / "topology.npz") as z:
        big = pieces(z["fragment"], 0.03)
    assert len(big) >= 2, f"pieces of >= 3 %: {big}"
    assert full["separated"] in (True, "yes") or full["piece_gap"] > 0.5, "the pieces come apart"
    video = imageio.get_reader(out / "full.mp4")
    first = last = video.get_data(0)
    for frame in video:  # to the last frame (list() would take the reader's length hint, which is unbounded)
        last = frame
    assert first.shape[:2] == (480, 640), "captured scenes are drawn at 640x480 on the CPU"
    keep = edge_strength(last) / edge_strength(first)
    assert keep >= 0.9, f"last frame keeps {keep:.2f} of frame 0's edge strength"
