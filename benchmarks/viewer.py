"""How fast `fracture-gs view` opens a large run and follows the frame slider, in a browser without a GPU.

    python benchmarks/viewer.py                              # 100k Gaussians, 40 frames, --preview 20000
    python benchmarks/viewer.py --preview 0                  # every Gaussian on every change
    python benchmarks/viewer.py --gaussians 20000 --frames 10   # a smoke run

Writes a synthetic run through render-sim's own writer (`viewer.record`): a slab of N Gaussians (σ ≈ 3 mm) that
splits in two at frame 1 and opens a little every frame. Then serves it (`viewer.server.Viewer`) and drives
Chromium (Debian's package) the way the tests do (`tests/browserutil.py`: WebGL on Mesa's llvmpipe under Xvfb,
or headless SwiftShader with FRACTURE_GS_HEADLESS=1; the JSON names the renderer):

* open: from the page's load event to the first finished draw of the frame's splats;
* scrub: the slider thumb focused and moved one frame with the keyboard (ArrowRight), to the first finished draw
  of the new frame (the preview, when the frame has more than --preview Gaussians) and of the whole frame;
* memory: bytes per Gaussian per frame on disk, the peak Python allocation (tracemalloc) of reading and packing
  one frame, and the packed frame kept in the viewer's cache.

A draw is timed in the page: a script wraps WebGL's texture uploads and instanced draws, and reads one pixel back
after the first draw that follows new splats, so that its time is when that draw finished, not when it was queued.
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
    spent = 0.0
    for k in range(frames + 1):
        m = means.clone()
        fragment = torch.where(right, 1, 0).int() if k else torch.full((n,), -1, dtype=torch.int32)
        band = ((means[:, 0].abs() < 0.01) & (k > 0)).int()
        m[:, 0] += torch.where(right, 1.0, -1.0) * 0.004 * k
        out = SimpleNamespace(frame=k, time=k * 0.01, means=m, covars=cov, fragment=fragment, band=band)
        t0 = time.perf_counter()
        rec.write(out, rgb, drawn)  # what render-sim's render thread pays per frame
        spent += time.perf_counter() - t0
    rec.close()
    return {"record_ms_per_frame": 1e3 * spent / (frames + 1)}


HOOK = """
window.__ev = [];
let pending = false;
const G = WebGL2RenderingContext.prototype;
for (const name of ['texImage2D', 'texSubImage2D']) {
  const orig = G[name];
  G[name] = function (...a) {
    const r = orig.apply(this, a);
    if (a.length >= 9 && a[7] === this.UNSIGNED_INT) {
      window.__ev.push(['upload', performance.now(), 0]);
      pending = true;
    }
    return r;
  };
}
const px = new Uint8Array(4);
for (const name of ['drawElementsInstanced', 'drawArraysInstanced']) {
  const orig = G[name];
  G[name] = function (...a) {
    const r = orig.apply(this, a);
    if (pending) {  // the first draw after new splats: wait for it to finish (one pixel read back), then note it
      this.readPixels(0, 0, 1, 1, this.RGBA, this.UNSIGNED_BYTE, px);
      window.__ev.push(['draw', performance.now(), a[a.length - 1]]);
      pending = false;
    }
    return r;
  };
}
"""
"""Recorded in the page: each upload of the splat texture, and the first instanced draw after it once finished
(with its instance count); other draws (viser redraws the scene every second) are left alone."""


def shown_after(page, t0: float, counts: tuple, timeout: float = 120.0) -> tuple[float, int]:
    """Page-clock time [ms] and splat count of the first finished draw of one of `counts` splats after a splat
    upload later than t0 (a preview the browser had no time to draw before the whole frame came is skipped)."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        uploaded = None
        for kind, t, n in page.evaluate("window.__ev"):
            if kind == "upload" and t > t0 and uploaded is None:
                uploaded = t
            elif kind == "draw" and uploaded is not None and t > uploaded and n in counts:
                return t, n
        time.sleep(0.02)
    raise TimeoutError(f"no draw of {counts} splats after {t0:.0f} ms")


def sent(viewer, frame: int, whole: bool, timeout: float = 60.0) -> int:
    """Gaussians the viewer sent for `frame`: its whole frame, or its first push (the preview)."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        pushes = [(full, count) for _, state, full, count in viewer.pushed if state[0] == frame]
        if whole and any(full for full, _ in pushes):
            return next(count for full, count in pushes if full)
        if not whole and pushes:
            return pushes[0][1]
        time.sleep(0.01)
    raise TimeoutError(f"frame {frame} never pushed")


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--gaussians", type=int, default=100_000)
    p.add_argument("--frames", type=int, default=40)
    p.add_argument("--preview", type=int, default=20_000, help="the viewer's --preview (0: every Gaussian at once)")
    p.add_argument("--max-splats", type=int, default=0, help="the viewer's --max-splats (0: every Gaussian)")
    p.add_argument("--scrubs", type=int, default=5)
    p.add_argument("--width", type=int, default=800)
    p.add_argument("--height", type=int, default=600)
    a = p.parse_args(argv)
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))  # the tests' browser helpers
    from browserutil import free_port, launch, renderer
    from playwright.sync_api import sync_playwright

    from fracture_gs.viewer import format as fmt
    from fracture_gs.viewer import panels
    from fracture_gs.viewer.server import Viewer
    from fracture_gs.viewer.store import open_run

    out: dict = {"gaussians": a.gaussians, "frames": a.frames, "preview": a.preview, "max_splats": a.max_splats}
    with tempfile.TemporaryDirectory() as tmp:
        out.update(make_run(Path(tmp), a.gaussians, a.frames))
        view = open_run(tmp)
        size = (Path(tmp) / "view" / "full.frames").stat().st_size
        assert fmt.frame_bytes(a.gaussians) * (a.frames + 1) == size
        out["disk_bytes_per_gaussian_frame"] = size / (a.frames + 1) / a.gaussians
        tracemalloc.start()
        t0 = time.perf_counter()
        buf = panels.frame_buffer(view.frame("full", 7), view.static["opacity"], 0.003)
        out["read_pack_ms"] = 1e3 * (time.perf_counter() - t0)
        out["read_pack_peak_bytes_per_gaussian"] = tracemalloc.get_traced_memory()[1] / a.gaussians
        tracemalloc.stop()
        out["cached_bytes_per_gaussian_frame"] = buf.nbytes / a.gaussians
        viewer = Viewer(view, port=free_port(), preview=a.preview, max_splats=a.max_splats)
        try:
            with sync_playwright() as pw:
                browser = launch(pw)
                page = browser.new_page(viewport={"width": a.width, "height": a.height})
                page.add_init_script(HOOK)
                page.goto(viewer.url)
                out["renderer"] = renderer(page)
                loaded = page.evaluate("performance.getEntriesByType('navigation')[0].loadEventEnd")
                out["open_s"] = (shown_after(page, 0.0, (sent(viewer, 0, True),))[0] - loaded) / 1e3
                page.wait_for_timeout(2000)
                thumb = page.locator("[role=slider]").first
                firsts, wholes, previews_drawn = [], [], 0
                for i in range(1, a.scrubs + 1):
                    thumb.focus()
                    t0 = page.evaluate("performance.now()")
                    page.keyboard.press("ArrowRight")
                    preview, whole = sent(viewer, i, False), sent(viewer, i, True)
                    first, n = shown_after(page, t0, (preview, whole))
                    firsts.append((first - t0) / 1e3)
                    previews_drawn += n != whole
                    done = first if n == whole else shown_after(page, first, (whole,))[0]
                    wholes.append((done - t0) / 1e3)
                    page.wait_for_timeout(2000)
                out["previews_drawn"] = previews_drawn
                out["scrub_first_s"] = statistics.median(firsts)
                out["scrub_whole_s"] = statistics.median(wholes)
                out["scrub_first_all_s"] = [round(x, 3) for x in firsts]
                out["scrub_whole_all_s"] = [round(x, 3) for x in wholes]
                browser.close()
        finally:
            viewer.close()
    print(json.dumps({k: round(v, 3) if isinstance(v, float) else v for k, v in out.items()}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
