"""Composer layouts, circular insets, interface regions and H.264 video output (CPU)."""

from __future__ import annotations

import math
import os
import random

import cv2
import numpy as np
import pytest
import torch

from fracture_gs.io.video import VideoWriter, read_video, save_png, write_video
from fracture_gs.render import look_at
from fracture_gs.render.compose import (
    add_inset,
    caption,
    caption_text,
    grid,
    inset_placement,
    interface_region,
    side_by_side,
)


def fresh_rng():
    """A fresh seed per test (FGS_SEED=<seed> reproduces a failure) and a numpy generator."""
    seed = int(os.environ.get("FGS_SEED", random.SystemRandom().randrange(2**31)))
    return seed, np.random.default_rng(seed)


def smooth_image(rng, h, w):
    """A smooth random RGB image (low-frequency), so bilinear magnification is well defined."""
    small = rng.integers(0, 256, (max(2, h // 12), max(2, w // 12), 3)).astype(np.float32)
    return np.clip(cv2.resize(small, (w, h), interpolation=cv2.INTER_CUBIC), 0, 255).astype(np.uint8)


def even(n):
    return n + n % 2


def test_caption_adds_bar_and_keeps_even_size():
    seed, rng = fresh_rng()
    img = rng.integers(0, 256, (51, 77, 3), dtype=np.uint8)
    out = caption(img, "FractureFields  t=0.100 s  #10")
    assert out.dtype == np.uint8 and out.shape[0] % 2 == 0 and out.shape[1] % 2 == 0, seed
    assert out.shape[1] == 78 and out.shape[0] > 51
    bar = out.shape[0] - 52  # 51 rows of image padded to 52
    np.testing.assert_array_equal(out[bar : bar + 51, :77], img, err_msg=f"seed {seed}")
    assert out[:bar].std() > 0, "caption text not drawn"


def test_side_by_side_and_grid_sizes():
    seed, rng = fresh_rng()
    a, b, c = (rng.integers(0, 256, s, dtype=np.uint8) for s in [(64, 48, 3), (60, 50, 3), (64, 41, 3)])
    out = side_by_side([a, b, c], gap=4)
    assert out.shape == (64, even(48 + 50 + 41 + 8), 3), seed
    np.testing.assert_array_equal(out[:, :48], a)
    np.testing.assert_array_equal(out[:60, 52:102], b)
    capd = side_by_side([a, b, c], ["baseline", "stress", "full"])
    assert capd.shape[1] == out.shape[1] and capd.shape[0] > 64 and capd.shape[0] % 2 == 0
    with pytest.raises(ValueError):
        side_by_side([a, b], ["only one"])
    g = grid([[a, b, c], [c, b, a]], row_labels=["t=0", "t=1"], col_labels=["baseline", "stress", "full"])
    assert g.shape[0] % 2 == 0 and g.shape[1] % 2 == 0
    plain = grid([[a, b, c], [c, b, a]])
    assert plain.shape == (even(2 * 64 + 4), even(3 * 50 + 2 * 4), 3)
    assert g.shape[0] > plain.shape[0] and g.shape[1] > plain.shape[1]
    # content: cell (r, k) holds its image at its top-left corner (cells 64 × 50, gap 4), white padding beside it
    for r, row in enumerate([[a, b, c], [c, b, a]]):
        for k, img in enumerate(row):
            y0, x0 = r * 68, k * 54
            np.testing.assert_array_equal(plain[y0 : y0 + img.shape[0], x0 : x0 + img.shape[1]], img, f"seed {seed}")
    assert (plain[60:64, 54:104] == 255).all(), "b's cell is padded below it"
    # with labels the same images sit below the label bar and right of the label column, in the same arrangement
    spots = {}
    for name, img in (("a", a), ("b", b), ("c", c)):
        res = cv2.matchTemplate(g, img, cv2.TM_SQDIFF)  # float sums: near-zero where the image sits, confirmed exactly
        near = np.argwhere(res < 1e-4 * float((img.astype(np.float64) ** 2).sum()))
        h, w = img.shape[:2]
        hits = [(y, x) for y, x in near if np.array_equal(g[y : y + h, x : x + w], img)]
        assert len(hits) == 2, f"{name} appears {len(hits)} times, not twice (seed {seed})"
        spots[name] = sorted(map(tuple, hits))
    (ya0, xa0), (ya1, xa1) = spots["a"]  # a: row 0 column 0, row 1 column 2
    assert ya1 - ya0 == 68 and xa1 - xa0 == 2 * 54 and ya0 > 0 and xa0 > 0
    assert spots["b"] == [(ya0, xa0 + 54), (ya1, xa0 + 54)]
    # float images in [0, 1] are accepted
    assert side_by_side([a / 255.0, torch.from_numpy(b / 255.0)]).dtype == np.uint8


@pytest.mark.parametrize("where", ["centre", "corner", "random"])
def test_inset_placement_avoids_source_and_magnifies(where):
    seed, rng = fresh_rng()
    h, w = 240, 320
    img = smooth_image(rng, h, w) if where != "random" else rng.integers(0, 256, (h, w, 3), dtype=np.uint8)
    r, zoom = 22.0, 2.5
    if where == "centre":
        c = (w / 2, h / 2)
    elif where == "corner":
        c = (40.0, 35.0)  # near the top-left: the inset must go elsewhere
    else:
        c = (float(rng.uniform(r, w - r)), float(rng.uniform(r, h - r)))
    ix, iy, R = inset_placement(img.shape, c, r, zoom)
    msg = f"seed {seed}, source {c}, inset {(ix, iy, R)}"
    assert math.hypot(ix - c[0], iy - c[1]) >= R + r, msg  # no overlap with the source circle
    assert R >= 8 and ix - R >= 0 and iy - R >= 0 and ix + R <= w and iy + R <= h, msg
    out = add_inset(img, c, r, zoom)
    assert out.shape == img.shape and out.dtype == np.uint8
    # pixels well inside the inset disc equal the source magnified by R/r about the source centre
    z = R / r
    ys, xs = np.mgrid[0:h, 0:w] + 0.5
    inner = (xs - ix) ** 2 + (ys - iy) ** 2 <= (R - 4) ** 2
    sx = np.clip(c[0] + (xs[inner] - ix) / z - 0.5, 0, w - 1)
    sy = np.clip(c[1] + (ys[inner] - iy) / z - 0.5, 0, h - 1)
    x0, y0 = np.floor(sx).astype(int), np.floor(sy).astype(int)
    x1, y1 = np.minimum(x0 + 1, w - 1), np.minimum(y0 + 1, h - 1)
    fx, fy = (sx - x0)[:, None], (sy - y0)[:, None]
    f = img.astype(np.float64)
    ref = (f[y0, x0] * (1 - fx) + f[y0, x1] * fx) * (1 - fy) + (f[y1, x0] * (1 - fx) + f[y1, x1] * fx) * fy
    assert np.abs(out[inner].astype(float) - ref).max() <= 1.0, msg
    # the source region itself is untouched inside its outline
    src = (xs - c[0]) ** 2 + (ys - c[1]) ** 2 <= (r - 3) ** 2
    np.testing.assert_array_equal(out[src], img[src], err_msg=msg)


def test_interface_region_projects_the_disc():
    cam = look_at((0.0, -2.0, 0.0), (0, 0, 0), (0, 0, 1), 40, 256, 192)
    f = float(cam.K[1, 1])
    cx, cy, r = interface_region((0, 0, 0), (0, 1, 0), 0.2, cam)  # disc facing the camera
    assert abs(cx - 128) < 1e-6 and abs(cy - 96) < 1e-6
    assert abs(r - f * 0.2 / 2.0) < 0.05 * r
    cx2, cy2, r2 = interface_region((0.3, 0, 0.1), (1, 0, 0), 0.2, cam)  # seen edge-on
    uv, _ = cam.project(torch.tensor([[0.3, 0.0, 0.1]]))
    assert abs(cx2 - float(uv[0, 0])) < 1e-3 and abs(cy2 - float(uv[0, 1])) < 1e-3
    assert r2 > 1.0
    with pytest.raises(ValueError):
        interface_region((0, -5, 0), (0, 1, 0), 0.1, cam)


def test_caption_text():
    s = caption_text("full", 0.25, 25)
    assert "FractureFields" in s and "0.250" in s and "25" in s
    assert caption_text("my_variant", 0.0, 0).startswith("my_variant")


def test_video_roundtrip_odd_size_padded(tmp_path):
    seed, rng = fresh_rng()
    frames = [rng.integers(0, 256, (33, 47, 3), dtype=np.uint8) for _ in range(7)]
    p = tmp_path / "v" / "out.mp4"
    assert write_video(p, frames, fps=12) == 7
    assert read_video(p) == (7, 34, 48), seed
    with VideoWriter(tmp_path / "f.mp4", fps=24) as vw:
        for k in range(5):
            vw.write(np.full((20, 30, 3), k / 5.0))  # float frames
    assert read_video(tmp_path / "f.mp4") == (5, 20, 30)
    # content: flat float frames come back as their grey level k/5 · 255 (within H.264's rounding), in order
    import imageio.v2 as imageio

    with imageio.get_reader(tmp_path / "f.mp4") as reader:
        levels = [float(np.asarray(f).mean()) for f in reader]
    assert levels == pytest.approx([round(k / 5 * 255) for k in range(5)], abs=3), levels
    # a moving square: each decoded frame has it where it was drawn (its brightest block), on black
    moving = []
    for k in range(4):
        f = np.zeros((48, 64, 3), np.uint8)
        f[10:26, 8 + 10 * k : 24 + 10 * k] = 255
        moving.append(f)
    write_video(tmp_path / "m.mp4", moving, fps=10)
    with imageio.get_reader(tmp_path / "m.mp4") as reader:
        for k, f in enumerate(reader):
            grey = np.asarray(f).mean(-1)
            ys, xs = np.nonzero(grey > 128)
            assert abs(xs.mean() - (15.5 + 10 * k)) < 1 and abs(ys.mean() - 17.5) < 1, (k, seed)
            assert grey[30:, :].max() < 40, "the background stays black"
    with pytest.raises(ValueError, match="same size"):
        with VideoWriter(tmp_path / "bad.mp4") as vw:
            vw.write(np.zeros((20, 30, 3), np.uint8))
            vw.write(np.zeros((22, 30, 3), np.uint8))


def test_save_png_roundtrip(tmp_path):
    seed, rng = fresh_rng()
    img = rng.integers(0, 256, (21, 30, 3), dtype=np.uint8)
    save_png(tmp_path / "a" / "x.png", img)
    back = cv2.imread(str(tmp_path / "a" / "x.png"))[..., ::-1]
    np.testing.assert_array_equal(back, img, err_msg=f"seed {seed}")


def test_comparison_composed_live_equals_composed_after(tmp_path):
    """The comparison video composed beside the last variant's run (frame i once that variant has it)
    writes the same frames as composing after every variant finished, including a variant that
    stopped early (it holds its last frame, captioned with its status) and the last variant ending
    after the others."""
    import threading
    import time

    from fracture_gs.config import SceneConfig
    from fracture_gs.render_sim.comparison import ComparisonVideo, compose_comparison

    cfg = SceneConfig(name="t", frame_dt=0.01)
    rng = np.random.default_rng(0)
    frames = {v: [rng.integers(0, 256, (24, 32, 3), dtype=np.uint8) for _ in range(n)] for v, n in (("a", 9), ("b", 5))}
    last = [rng.integers(0, 256, (24, 32, 3), dtype=np.uint8) for _ in range(12)]
    statuses = ["ok", "diverged at frame 5: CFL", "ok"]
    variants = ["a", "b", "c"]
    after = tmp_path / "after"
    compose_comparison(cfg, variants, [frames["a"], frames["b"], last], None, after, statuses)
    live_dir, growing = tmp_path / "live", []
    live = ComparisonVideo(cfg, variants, [frames["a"], frames["b"], growing], None, live_dir, statuses[:2] + ["ok"])
    live.start_live(growing)

    def produce():
        for img in last:
            growing.append(img)
            time.sleep(0.01)

    t = threading.Thread(target=produce)
    t.start()
    t.join()
    live.finish(statuses)
    names = sorted(p.name for p in (after / "frames").iterdir())
    assert len(names) == 12 and names == sorted(p.name for p in (live_dir / "frames").iterdir())
    for n in names:
        assert np.array_equal(cv2.imread(str(after / "frames" / n)), cv2.imread(str(live_dir / "frames" / n))), n
    assert read_video(live_dir / "comparison.mp4")[0] == 12


def test_missing_encoder_is_one_sentence_naming_the_fix(tmp_path, monkeypatch):
    """An environment without imageio-ffmpeg (a dependency, but environments get assembled by hand) gets an
    OutputError that names the package and the pip command when the first frame is written, not an
    ImportError traceback from the writer thread."""
    import sys

    from fracture_gs.errors import OutputError

    monkeypatch.setitem(sys.modules, "imageio_ffmpeg", None)  # `import imageio_ffmpeg` now raises ImportError
    writer = VideoWriter(tmp_path / "out.mp4", fps=10)
    with pytest.raises(OutputError, match="pip install imageio-ffmpeg"):
        writer.write(np.zeros((8, 8, 3), dtype=np.uint8))


def test_encoder_without_an_executable_is_one_sentence(tmp_path, monkeypatch):
    """imageio-ffmpeg installed but no ffmpeg executable found (a wheel unpacked without its binary's
    execute bit, a stripped image): an OutputError naming the ways to get one, not a RuntimeError traceback."""
    import imageio_ffmpeg

    from fracture_gs.errors import OutputError

    def missing():
        raise RuntimeError("No ffmpeg exe could be found.")

    monkeypatch.setattr(imageio_ffmpeg, "get_ffmpeg_exe", missing)
    writer = VideoWriter(tmp_path / "out.mp4", fps=10)
    with pytest.raises(OutputError, match="IMAGEIO_FFMPEG_EXE"):
        writer.write(np.zeros((8, 8, 3), dtype=np.uint8))


def test_comparison_insets_appear_from_the_latch_frame(tmp_path):
    """With a latched interface at the camera target, every comparison frame from the latch frame on
    carries the insets (it differs from the same run composed without a topology) and the frames before
    it do not."""
    from types import SimpleNamespace

    from fracture_gs.config import SceneConfig
    from fracture_gs.render_sim.comparison import compose_comparison

    cfg = SceneConfig(name="t", frame_dt=0.01, frames=8)
    cfg.render.width, cfg.render.height = 32, 24
    topology = SimpleNamespace(point=list(cfg.render.camera.target), normal=[1.0, 0.0, 0.0], latch_frame=3)
    rng = np.random.default_rng(1)
    lists = [[rng.integers(0, 256, (24, 32, 3), dtype=np.uint8) for _ in range(8)] for _ in range(2)]
    compose_comparison(cfg, ["a", "b"], lists, topology, tmp_path / "inset")
    compose_comparison(cfg, ["a", "b"], lists, None, tmp_path / "plain")
    names = sorted(p.name for p in (tmp_path / "inset" / "frames").iterdir())
    same = [np.array_equal(*(cv2.imread(str(tmp_path / d / "frames" / n)) for d in ("inset", "plain"))) for n in names]
    assert same == [True] * 3 + [False] * 5
