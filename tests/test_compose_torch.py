"""The torch composer of the comparison frame (`render.compose_torch.compose_row`) against the numpy one
(`render.compose.side_by_side` over `add_inset` panels, the reference it replaces in render-sim): the same bytes,
on the CPU here and on CUDA where there is one; and what render-sim hands it (`painter.DrawnFrame`)."""

from __future__ import annotations

from types import SimpleNamespace

import cv2
import numpy as np
import pytest
import torch

from fracture_gs.config import SceneConfig
from fracture_gs.render import compose
from fracture_gs.render.compose_torch import Inset, compose_row
from fracture_gs.render_sim.comparison import ComparisonVideo
from fracture_gs.render_sim.painter import DEVICE_FRAMES_BYTES, DrawnFrame, Painter

DEVICES = ["cpu"] + (["cuda"] if torch.cuda.is_available() else [])


def smooth_image(rng, h, w):
    """A smooth random RGB image (a few colour blobs), like a rendered frame: bilinear samples fall between levels."""
    small = rng.integers(0, 256, (max(2, h // 10), max(2, w // 10), 3)).astype(np.float32)
    return np.clip(cv2.resize(small, (w, h), interpolation=cv2.INTER_CUBIC), 0, 255).astype(np.uint8)


def numpy_row(images, captions, insets, gap=4):
    """The numpy path: each panel with its inset (`add_inset`), then side by side under the captions."""
    panels = [compose.add_inset(i, s.center, s.radius, s.zoom) if s else i for i, s in zip(images, insets)]
    return compose.side_by_side(panels, captions, gap)


def random_row(rng, odd: bool):
    """Two or three panels of one even size (or, `odd`, of sizes up to three pixels apart, odd ones included), each
    with an inset somewhere in it (near an edge or a corner too, zoom 1-4) or none, and render-sim's captions."""
    n = int(rng.integers(2, 4))
    h, w = int(rng.integers(15, 61)) * 2, int(rng.integers(20, 81)) * 2
    sizes = [(h + int(rng.integers(-3, 4)), w + int(rng.integers(-3, 4))) if odd else (h, w) for _ in range(n)]
    images = [smooth_image(rng, hh, ww) for hh, ww in sizes]
    insets = [
        Inset(
            (float(rng.uniform(0, ww)), float(rng.uniform(0, hh))), float(rng.uniform(3, 30)), float(rng.uniform(1, 4))
        )
        if rng.random() < 0.8
        else None
        for hh, ww in sizes
    ]
    frame = int(rng.integers(0, 300))
    captions = [compose.caption_text(v, frame * 0.01, frame) for v in ["baseline", "stress_zero", "full"][:n]]
    captions[-1] += "  diverged" if rng.random() < 0.3 else ""  # a variant that stopped holds its last frame
    return images, captions, insets, int(rng.integers(0, 6))


@pytest.mark.parametrize("device", DEVICES)
@pytest.mark.parametrize("seed", range(6))
def test_the_torch_composer_gives_the_numpy_composers_bytes(device, seed):
    """A comparison frame composed as torch ops (panels copied into a canvas, each inset disc magnified by bilinear
    sampling on the device; strokes, caption bars and edge padding on the host after one copy) equals the numpy
    path's byte for byte: panels with and without insets (near edges, zoom 1-4), captions, even and odd sizes,
    any gap. Exact by construction (the same formula, dtypes and order of operations), so a changed rounding, a
    misplaced panel, a stroke drawn in the wrong order or a padding row left unfilled shows as a byte off."""
    rng = np.random.default_rng(seed)
    for odd in (False, True):
        for _ in range(4):
            images, captions, insets, gap = random_row(rng, odd)
            expected = numpy_row(images, captions, insets, gap)
            panels = [torch.from_numpy(i).to(device) for i in images]
            got = compose_row(panels, captions, insets, gap)
            assert isinstance(got, np.ndarray) and got.dtype == np.uint8
            torch.testing.assert_close(torch.from_numpy(got), torch.from_numpy(expected), atol=0, rtol=0)
    # and without captions, from numpy panels
    images, _, insets, gap = random_row(rng, True)
    torch.testing.assert_close(
        torch.from_numpy(compose_row(images, None, insets, gap, device=device)),
        torch.from_numpy(numpy_row(images, None, insets, gap)),
        atol=0,
        rtol=0,
    )


def test_the_inset_is_drawn_and_magnified():
    """The composer's frame is not the plain row: with an inset the disc shows the source region magnified, so
    the two differ inside the inset disc and agree far from it (a composer that forgot the inset or drew it
    everywhere fails)."""
    rng = np.random.default_rng(7)
    images = [smooth_image(rng, 96, 128) for _ in range(2)]
    inset = Inset((64.0, 48.0), 10.0, 3.0)
    plain = compose_row(images, None, [None, None], gap=4)
    with_inset = compose_row(images, None, [inset, None], gap=4)
    ix, iy, R, _, _ = compose.inset_geometry((96, 128), inset.center, inset.radius, inset.zoom)
    y0, y1, x0, x1, disc = compose.disc_box((96, 128), (ix, iy), R)
    inside = (with_inset[y0:y1, x0:x1] != plain[y0:y1, x0:x1]).any(-1)[disc]
    assert inside.mean() > 0.5, "the inset disc shows something else than the plain panel"
    np.testing.assert_array_equal(with_inset[:, 132:], plain[:, 132:])  # the second panel has no inset


def test_a_caption_is_drawn_once_per_distinct_text(monkeypatch):
    """Caption bars are drawn once per distinct text and size and pasted after that (a variant that stopped holds
    its last frame and caption for every later frame): composing the same captions again draws no text."""
    calls = []
    real = cv2.putText
    monkeypatch.setattr(cv2, "putText", lambda *a, **k: calls.append(a[1]) or real(*a, **k))
    rng = np.random.default_rng(3)
    images = [smooth_image(rng, 40, 64) for _ in range(2)]
    captions = ["once-a  t=9.870 s  #987", "once-b  t=9.870 s  #987  interrupted"]
    first = compose_row(images, captions)
    assert sorted(calls) == sorted(captions)
    again = compose_row(images, captions)
    assert sorted(calls) == sorted(captions), "the second frame drew its captions again"
    np.testing.assert_array_equal(first, again)


def test_the_comparison_composes_the_frames_kept_on_the_device(tmp_path):
    """A variant's frame that carries its device copy (`DrawnFrame`, render-sim on CUDA) is composed from that
    copy, not re-uploaded from the host: here the two are made to differ, and the comparison frame shows the
    device copy. Its host copy is a plain array for every numpy reader (np.stack, the variant video)."""
    rng = np.random.default_rng(5)
    shown = [smooth_image(rng, 24, 32) for _ in range(2)]
    frames = []
    for img in shown:
        frame = DrawnFrame.of(torch.from_numpy(img.copy()))
        frame.device_image = frame.device_image.clone()  # on the CPU both would share memory; on CUDA they do not
        frame[:] = 0  # the host copy differs from the device copy from here on
        frames.append([frame])
    assert type(np.stack([f[0] for f in frames])) is np.ndarray
    assert frames[0][0][1:].device_image is None, "a slice is not the frame: it holds no device copy"
    cfg = SceneConfig(name="t", frame_dt=0.01)
    video = ComparisonVideo(cfg, ["baseline", "full"], frames, None, tmp_path, ["ok", "ok"], frames_png=False)
    try:
        got = video.frame(0)
    finally:
        video.abort()
    captions = [compose.caption_text(v, 0.0, 0) for v in ("baseline", "full")]
    np.testing.assert_array_equal(got, compose.side_by_side(shown, captions))


def test_a_run_keeps_its_frames_on_the_device_only_within_the_budget():
    """On CUDA a variant's frames stay on the device for the composer while the run's frames (frames + 1, every
    variant) fit DEVICE_FRAMES_BYTES: the bread paper preset (90 frames, 3 variants, 320×240) does, 400 frames at
    1080p do not; on the CPU there is no second copy to keep."""

    def fits(device: str, frames: int, width: int, height: int) -> bool:
        render = SimpleNamespace(width=width, height=height)
        cfg = SimpleNamespace(frames=frames, variants=["baseline", "stress_zero", "full"], render=render)
        painter = SimpleNamespace(cov0=SimpleNamespace(device=torch.device(device)), scene_cfg=cfg)
        return Painter._frames_fit_device(painter)

    assert fits("cuda", 90, 320, 240) and not fits("cuda", 400, 1920, 1080)
    assert fits("cuda", DEVICE_FRAMES_BYTES // (3 * 10 * 10 * 3) - 1, 10, 10)
    assert not fits("cuda", DEVICE_FRAMES_BYTES // (3 * 10 * 10 * 3), 10, 10)
    assert not fits("cpu", 90, 320, 240)
