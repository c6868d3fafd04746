"""A real render-sim run in the viewer: the job records what it simulated and drew (view/), the record agrees with
the run's other outputs, and the browser draws it.

The bread at 2,500 particles, 12 frames, `baseline` and `full`: the stress event latches and the loaf breaks in
two, so the last frame of `full` holds two fragments.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
from runutil import tiny_bread

from fracture_gs.viewer import format as fmt
from fracture_gs.viewer.store import open_run

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def bread(tmp_path_factory):
    from fracture_gs.render_sim import run_render_sim

    out = tmp_path_factory.mktemp("bread")
    cfg = tiny_bread(frames=12)
    run_render_sim(cfg, ["baseline", "full"], "cpu", out, progress=False)
    return out, cfg


def test_render_sim_records_what_it_simulated(bread):
    """view/ holds every frame (0 … 12) of both variants; frame 0 is the prepared scene at rest (centres within
    the quantisation step); the last frame's fragment ids are the latched topology of topology.npz, and the
    Gaussians drawn are the surface plus the interior the cut exposed."""
    import torch

    from fracture_gs.pipeline import prepare_scene
    from fracture_gs.sim.topology import load_history

    out, cfg = bread
    view = open_run(out)
    assert view.counts == {"baseline": 13, "full": 13} and view.notes == []
    scene = prepare_scene(cfg, "cpu")
    rest = scene.gaussians.means.numpy()
    first = view.frame("full", 0)
    step = (rest.max(0) - rest.min(0)) / 65535
    assert (np.abs(first.means - rest) <= step / 2 + 1e-6).all()
    last = view.frame("full", 12)
    topo = load_history(out / "topology.npz")[-1]
    assert last.fragment.tolist() == topo.fragment.to(torch.int16).tolist()
    assert sorted(np.unique(last.fragment).tolist()) == [0, 1]
    interior = scene.gaussians.interior.numpy()
    drawn = (last.flags & fmt.DRAWN) != 0
    assert drawn[~interior].all() and 0 < drawn[interior].sum() < interior.sum()
    assert ((last.flags & fmt.INTERFACE) != 0).sum() > 0


def test_no_view_record_writes_none(tmp_path):
    """`record_view=False` (render-sim --no-view-record) leaves no view/ folder, and the viewer says so."""
    from fracture_gs.errors import ViewError
    from fracture_gs.render_sim import run_render_sim

    run_render_sim(tiny_bread(frames=2), ["baseline"], "cpu", tmp_path, progress=False, record_view=False)
    assert not (tmp_path / "view").exists()
    with pytest.raises(ViewError, match="without the viewer's record"):
        open_run(tmp_path)


def test_the_browser_draws_the_broken_loaf(bread):
    """The page draws the run: `full` at its last frame, coloured by fragment, shows two pieces in two hues; the
    screenshot (controls visible) is what README's tour shows (kept where $FRACTURE_GS_VIEWER_SHOTS says)."""
    from browserutil import free_port, ink, launch, settled
    from playwright.sync_api import sync_playwright

    from fracture_gs.viewer.panels import fragment_rgb
    from fracture_gs.viewer.server import Viewer

    viewer = Viewer(open_run(bread[0]), port=free_port())
    try:
        with sync_playwright() as p:
            browser = launch(p)
            page = browser.new_page(viewport={"width": 640, "height": 420})
            page.goto(viewer.url)
            viewer.variant.value, viewer.color.value, viewer.frame.value = "full", "fragment", 12
            img = settled(page, viewer, (12, ("full",), "fragment", False, True))
            mask = ink(img)
            assert mask.mean() > 0.03
            hues = fragment_rgb(np.array([0, 1]), np.full((2, 3), 0.8)) * 255  # the palette's two colours, lit
            pixels = img[mask].astype(float)  # [M,3]
            near = np.linalg.norm(pixels[:, None] - hues[None], axis=-1).argmin(1)
            assert min((near == 0).mean(), (near == 1).mean()) > 0.15, "both fragments drawn in their own hue"
            shots = os.environ.get("FRACTURE_GS_VIEWER_SHOTS")
            if shots:  # both variants side by side, for the README
                page.set_viewport_size({"width": 1000, "height": 420})
                viewer.side.value = True
                settled(page, viewer, (12, ("baseline", "full"), "fragment", False, True))
                page.locator(".mantine-Notification-closeButton").first.click()
                page.wait_for_timeout(500)
                page.screenshot(path=str(Path(shots) / "viewer.png"))
            browser.close()
    finally:
        viewer.close()


def test_render_sim_view_opens_the_viewer_on_the_finished_run(tmp_path, monkeypatch, capsys):
    """`render-sim --view` checks the port before simulating, runs, then serves the run it just wrote: the viewer
    gets that folder's record with every frame of each variant (serving is replaced here by a stand-in that
    returns at once)."""
    from fracture_gs import cli
    from fracture_gs.viewer import server

    checked, served = [], []
    monkeypatch.setattr(server, "check_port", lambda host, port: checked.append((host, port)))
    monkeypatch.setattr(server, "serve", lambda view, **kw: served.append(view) or 0)
    out = tmp_path / "run"
    args = ["render-sim", "bread", "--frames", "3", "--variants", "baseline,full", "--out", str(out), "--view"]
    assert cli.main([*args, "--particles", "1500", "--resolution", "64x48", "--device", "cpu"]) == 0
    assert checked == [("127.0.0.1", 8080)]
    assert len(served) == 1 and served[0].run_dir == out and served[0].counts == {"baseline": 4, "full": 4}
    assert f"view/ (fracture-gs view {out})" in capsys.readouterr().out
