"""How fast `fracture-gs view` opens a large run and follows the frame slider, in a browser without a GPU.

    python benchmarks/viewer.py                              # 100k Gaussians, 40 frames, --preview 20000
    python benchmarks/viewer.py --preview 0                  # every Gaussian on every change
    python benchmarks/viewer.py --gaussians 20000 --frames 10   # a smoke run

Writes a synthetic run through render-sim's own writer (`viewer.record`): a slab of N Gaussians (σ ≈ 3 mm) that
splits in two at frame 1 and opens a little every frame. Then serves it (`viewer.server.Viewer`) and drives
headless Chromium (Debian's package, WebGL in software: SwiftShader) the way the tests do:

* open: from the page's load event to the first picture with the object drawn, and to the whole frame drawn;
* scrub: the slider thumb focused and moved one frame with the keyboard, to the first changed picture (the
  preview, when the frame has more than --preview Gaussians) and to the whole frame drawn and settled;
* memory: bytes per Gaussian per frame on disk, and the peak Python allocation (tracemalloc) of reading and
  packing one frame, and the packed frame kept in the viewer's cache.

"Drawn" is observed by taking screenshots, so each time includes one screenshot (an upper bound).
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
import time
import tracemalloc
from pathlib import Path
from types import SimpleNamespace

import numpy as np


def make_run(out: Path, n: int, frames: int) -> dict:
    """A slab 40 × 20 × 10 cm of n Gaussians, one variant (`full`), split at x = 0 from frame 1 on."""
    import torch

    from fracture_gs.config import CameraConfig, SceneConfig
    from fracture_gs.io import GaussianSet
    from fracture_gs.sh import SH_C0
    from fracture_gs.viewer.record import FrameRecorder, start_record

    rng = np.random.default_rng(0)
    means = torch.tensor(rng.uniform([-0.2, -0.1, 0.0], [0.2, 0.1, 0.1], (n, 3)), dtype=torch.float32)
    rgb = torch.tensor(np.c_[0.75 + 0.2 * rng.random(n), 0.55 + 0.1 * rng.random(n), 0.3 * np.ones(n)]).float()
    gs = GaussianSet(
        means=means,
        quats=torch.tensor([[1.0, 0, 0, 0]]).repeat(n, 1),
        scales=torch.full((n, 3), 0.003),
        opacities=torch.full((n,), 0.9),
        sh=((rgb - 0.5) / SH_C0)[:, None, :],
    )
    cfg = SceneConfig(name="slab", frames=frames, frame_dt=0.01)
    cfg.render.camera = CameraConfig(eye=(0.0, -0.7, 0.35), target=(0.0, 0.0, 0.05), up=(0.0, 0.0, 1.0))
    folder = start_record(out, cfg, gs, None, ["full"])
    rec = FrameRecorder(folder, "full")
    cov = gs.covariances()
    right = means[:, 0] > 0
    drawn = torch.ones(n, dtype=torch.bool)
    t0 = time.perf_counter()
    for k in range(frames + 1):
        m = means.clone()
        fragment = torch.where(right, 1, 0).int() if k else torch.full((n,), -1, dtype=torch.int32)
        band = ((means[:, 0].abs() < 0.01) & (k > 0)).int()
        m[:, 0] += torch.where(right, 1.0, -1.0) * 0.004 * k
        rec.write(
            SimpleNamespace(frame=k, time=k * 0.01, means=m, covars=cov, fragment=fragment, band=band), rgb, drawn
        )
    rec.close()
    return {"write_ms_per_frame": 1e3 * (time.perf_counter() - t0) / (frames + 1)}


def wait_full(viewer, frame: int, timeout: float) -> None:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if viewer.pushed and viewer.pushed[-1][2] and viewer.pushed[-1][1][0] == frame:
            return
        time.sleep(0.01)
    raise TimeoutError(f"frame {frame} never pushed whole")


def settle(page, before, timeout: float) -> tuple[float, np.ndarray]:
    """Seconds until two shots in a row agree (and differ from `before` when given)."""
    from browserutil import picture

    t0, end = time.perf_counter(), time.monotonic() + timeout
    last = picture(page)
    while time.monotonic() < end:
        now = picture(page)
        if np.abs(now.astype(int) - last).max() <= 2 and (before is None or np.abs(now.astype(int) - before).max() > 8):
            return time.perf_counter() - t0, now
        last = now
    raise TimeoutError("the picture never settled")


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--gaussians", type=int, default=100_000)
    p.add_argument("--frames", type=int, default=40)
    p.add_argument("--preview", type=int, default=20_000, help="the viewer's --preview (0: every Gaussian at once)")
    p.add_argument("--scrubs", type=int, default=5)
    p.add_argument("--width", type=int, default=800)
    p.add_argument("--height", type=int, default=600)
    a = p.parse_args(argv)
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))  # the tests' browser helpers
    from browserutil import free_port, ink, launch, picture
    from playwright.sync_api import sync_playwright

    from fracture_gs.viewer import format as fmt
    from fracture_gs.viewer import panels
    from fracture_gs.viewer.server import Viewer
    from fracture_gs.viewer.store import open_run

    out: dict = {"gaussians": a.gaussians, "frames": a.frames, "preview": a.preview}
    with tempfile.TemporaryDirectory() as tmp:
        out.update(make_run(Path(tmp), a.gaussians, a.frames))
        view = open_run(tmp)
        size = (Path(tmp) / "view" / "full.frames").stat().st_size
        out["disk_bytes_per_gaussian_frame"] = size / (a.frames + 1) / a.gaussians
        tracemalloc.start()
        t0 = time.perf_counter()
        buf = panels.frame_buffer(view.frame("full", 7), view.static["opacity"], 0.003)
        out["read_pack_ms"] = 1e3 * (time.perf_counter() - t0)
        out["read_pack_peak_bytes_per_gaussian"] = tracemalloc.get_traced_memory()[1] / a.gaussians
        tracemalloc.stop()
        out["cached_bytes_per_gaussian_frame"] = buf.nbytes / a.gaussians
        assert fmt.frame_bytes(a.gaussians) * (a.frames + 1) == size
        viewer = Viewer(view, port=free_port(), preview=a.preview)
        try:
            with sync_playwright() as pw:
                browser = launch(pw)
                page = browser.new_page(viewport={"width": a.width, "height": a.height})
                page.goto(viewer.url)  # returns at the load event
                t0 = time.perf_counter()
                while ink(picture(page)).mean() < 0.01:
                    if time.perf_counter() - t0 > 120:
                        raise TimeoutError("nothing drawn in 120 s")
                out["open_first_picture_s"] = time.perf_counter() - t0
                settle(page, None, 120)
                out["open_whole_frame_s"] = time.perf_counter() - t0
                thumb = page.locator("[role=slider]").first
                firsts, wholes = [], []
                for i in range(a.scrubs):
                    before = picture(page)
                    thumb.focus()
                    t0 = time.perf_counter()
                    page.keyboard.press("ArrowRight")
                    while np.abs(picture(page).astype(int) - before).max() <= 8:
                        if time.perf_counter() - t0 > 60:
                            raise TimeoutError("the picture never changed")
                    firsts.append(time.perf_counter() - t0)
                    wait_full(viewer, i + 1, 60)
                    settle(page, None, 60)
                    wholes.append(time.perf_counter() - t0)
                out["scrub_first_picture_s"] = statistics.median(firsts)
                out["scrub_whole_frame_s"] = statistics.median(wholes)
                out["scrub_first_picture_all_s"] = [round(x, 3) for x in firsts]
                out["scrub_whole_frame_all_s"] = [round(x, 3) for x in wholes]
                browser.close()
        finally:
            viewer.close()
    print(json.dumps({k: round(v, 3) if isinstance(v, float) else v for k, v in out.items()}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
