"""`fracture-gs view` in a real browser: headless Chromium (Debian's package, driven by playwright) opens the page
and draws the run's splats in software WebGL; every control is worked the way a user works it (keyboard on the
frame slider, clicks on the dropdowns, checkboxes and buttons, a mouse drag to orbit), and what the canvas shows
is checked against what the run holds.

The run (tests/viewutil.py): a red block (x < 0.5) beside a blue one, seen by the video camera from −y with z
up, so red is on the left. In `full` they fracture at frame 1 and move 3 cm apart each frame; in `baseline`
they stay together.
"""

from __future__ import annotations

import io
import os
import time
from pathlib import Path

import numpy as np
import pytest
from browserutil import free_port, ink, launch, picture, settled
from viewutil import make_run

from fracture_gs.viewer.server import Viewer
from fracture_gs.viewer.store import open_run

pytestmark = pytest.mark.slow

LAST = 6


@pytest.fixture(scope="module")
def session(tmp_path_factory):
    from playwright.sync_api import sync_playwright

    run = make_run(tmp_path_factory.mktemp("run"), frames=LAST)
    viewer = Viewer(open_run(run), port=free_port())
    with sync_playwright() as p:
        browser = launch(p)
        page = browser.new_page(viewport={"width": 640, "height": 480}, accept_downloads=True)
        page.goto(viewer.url)
        yield page, viewer, run
        browser.close()
    viewer.close()


def show(viewer, frame: int, variant: str, side: bool = False, color: str = "scene") -> tuple:
    """Set the viewer's state from Python (a test's starting point; the action under test is in the browser)."""
    viewer.side.value, viewer.color.value, viewer.variant.value, viewer.frame.value = side, color, variant, frame
    return (frame, ("baseline", "full") if side else (variant,), color, False, True)


def red(img):
    r, g, b = np.moveaxis(img.astype(int), -1, 0)
    return (r > g + 60) & (r > b + 60)


def blue(img):
    r, g, b = np.moveaxis(img.astype(int), -1, 0)
    return (b > r + 60) & (b > g + 30)


def columns(mask) -> np.ndarray:
    return np.nonzero(mask.any(0))[0]


def runs(cols: np.ndarray) -> int:
    """Contiguous runs of column indices (gaps of more than 3 px split them)."""
    return 0 if len(cols) == 0 else 1 + int((np.diff(cols) > 3).sum())


def test_page_draws_the_run_where_the_camera_looks(session):
    """The page opens on the video camera and draws the splats there: the canvas is not blank, the blocks sit
    where the camera looks (the ink's centroid at the picture's centre: the camera's target is the blocks'
    centre), and red lies left of blue, as a camera at −y with z up sees x growing to the right."""
    page, viewer, _ = session
    img = settled(page, viewer, show(viewer, 0, "baseline"))
    h, w = img.shape[:2]
    mask = ink(img)
    assert mask.mean() > 0.05, f"the canvas is nearly blank ({mask.mean():.3f} of pixels drawn)"
    ys, xs = np.nonzero(mask)
    assert abs(xs.mean() - w / 2) < 0.06 * w and abs(ys.mean() - h / 2) < 0.08 * h, (xs.mean(), ys.mean())
    assert red(img).sum() > 1000 and blue(img).sum() > 1000
    assert np.nonzero(red(img))[1].mean() < w / 2 < np.nonzero(blue(img))[1].mean()
    shots = os.environ.get("FRACTURE_GS_VIEWER_SHOTS")  # where to keep the pictures, for a look by eye
    if shots:
        import imageio.v3 as iio

        iio.imwrite(Path(shots) / "blocks_frame0.png", img)


def test_moving_the_frame_slider_changes_the_picture(session):
    """The frame slider, moved with the keyboard in the browser (End: the last frame), takes the server to frame
    6 and the picture with it: in `full` the blocks have moved 2 × 18 cm apart, so the red block's left edge moved
    left, the blue block's right edge right, and a gap opened between them."""
    page, viewer, _ = session
    before = settled(page, viewer, show(viewer, 0, "full"))
    page.locator("[role=slider]").first.focus()
    page.keyboard.press("End")
    after = settled(page, viewer, (LAST, ("full",), "scene", False, True))
    assert int(viewer.frame.value) == LAST
    r0, b0, r1, b1 = (columns(f(img)) for img in (before, after) for f in (red, blue))
    assert r1.min() < r0.min() - 10 and b1.max() > b0.max() + 10
    assert b1.min() - r1.max() > b0.min() - r0.max() + 10, "a gap opened between the fragments"


def test_toggling_the_variant_changes_the_picture(session):
    """The variant dropdown, picked with the mouse, swaps what is drawn at the same frame: `baseline`'s blocks
    touch (one run of ink columns), `full`'s have split (red and blue a gap apart)."""
    page, viewer, _ = session
    base = settled(page, viewer, show(viewer, LAST, "baseline"))
    page.locator(".mantine-Select-input:visible").nth(0).click()
    page.get_by_role("option", name="full", exact=True).click()
    full = settled(page, viewer, (LAST, ("full",), "scene", False, True))
    assert viewer.variant.value == "full"
    assert runs(columns(ink(base))) == 1
    assert columns(blue(full)).min() - columns(red(full)).max() > 10
    assert np.abs(full.astype(int) - base).max(-1).mean() > 5


def test_side_by_side_draws_every_variant(session):
    """`side by side`, ticked in the browser, draws both variants at once: two red blocks, one per panel, and
    three separate pieces of ink across the picture (`baseline`'s blocks touch, `full`'s have split)."""
    page, viewer, _ = session
    settled(page, viewer, show(viewer, LAST, "full"))
    assert runs(columns(red(picture(page)))) == 1
    page.get_by_text("side by side").click()
    img = settled(page, viewer, (LAST, ("baseline", "full"), "scene", False, True))
    assert runs(columns(red(img))) == 2
    assert runs(columns(ink(img)[red(img).any(1)])) == 3  # in the blocks' rows (the labels are above them)
    show(viewer, LAST, "full")


def test_colour_by_fragment_paints_each_piece_its_hue(session):
    """`colour: fragment` paints each fragment in its palette hue (`panels.fragment_rgb`): the left block, fragment
    0, turns from red to fragment 0's colour."""
    from fracture_gs.viewer.panels import fragment_rgb

    page, viewer, _ = session
    settled(page, viewer, show(viewer, LAST, "full"))
    page.locator(".mantine-Select-input:visible").nth(1).click()
    page.get_by_role("option", name="fragment", exact=True).click()
    img = settled(page, viewer, (LAST, ("full",), "fragment", False, True))
    want = fragment_rgb(np.array([0]), np.array([[0.85, 0.15, 0.1]]))[0] * 255  # the left block's own red
    mask = ink(img)
    left = mask & (np.arange(img.shape[1]) < columns(mask).min() + 40)[None, :]
    got = np.median(img[left], 0)
    own = np.array([0.85, 0.15, 0.1]) * 255
    assert np.linalg.norm(got - want) < 35 < 50 < np.linalg.norm(got - own), (got, want, own)
    show(viewer, LAST, "full")


def test_video_camera_button_brings_the_view_back(session):
    """Orbiting with a mouse drag changes the view; the `video camera` button puts the camera back where the
    videos' camera is, and the picture with it."""
    page, viewer, _ = session
    home = settled(page, viewer, show(viewer, 0, "baseline"))
    page.mouse.move(200, 240)
    page.mouse.down()
    page.mouse.move(330, 200, steps=8)
    page.mouse.up()
    page.wait_for_timeout(800)
    moved = picture(page)
    assert np.abs(moved.astype(int) - home).max(-1).mean() > 3
    page.get_by_role("button", name="video camera").click()
    page.wait_for_timeout(1500)
    back = picture(page)
    assert np.abs(back.astype(int) - home).max(-1).mean() < 1.0


def test_save_png_button_downloads_the_view_and_keeps_it(session):
    """`save PNG` renders the current view in the browser and hands it over twice: as a download, and as a file
    in RUN_DIR/views/; both are the same picture of the blocks (red and blue on a transparent background)."""
    import imageio.v3 as iio

    page, viewer, run = session
    settled(page, viewer, show(viewer, 0, "baseline"))
    with page.expect_download(timeout=30_000) as info:
        page.get_by_role("button", name="save PNG").click()
    data = Path(info.value.path()).read_bytes()
    kept = sorted((run / "views").glob("*.png"))
    assert len(kept) == 1 and kept[0].read_bytes() == data
    assert kept[0].name == "blocks_baseline_f0000.png"
    img = iio.imread(io.BytesIO(data))
    assert img.shape[-1] == 4 and 0.05 < (img[..., 3] > 0).mean() < 0.95
    rgb = img[..., :3][img[..., 3] > 200]
    assert ((rgb[:, 0].astype(int) > rgb[:, 2] + 60).sum() > 500) and (
        (rgb[:, 2].astype(int) > rgb[:, 0] + 60).sum() > 500
    )


def test_background_of_a_capture_is_drawn_and_toggled(session, tmp_path):
    """A run with static background Gaussians (a capture's floor here) draws them under the object; unticking
    `background` in the browser removes them (less ink, the floor's grey gone)."""
    page, _, _ = session
    viewer = Viewer(open_run(make_run(tmp_path, frames=2, background=True)), port=free_port())
    try:
        page.goto(viewer.url)
        with_floor = settled(page, viewer, None)
        page.get_by_text("background", exact=True).click()
        without = settled(page, viewer, (0, ("baseline",), "scene", False, False))
        grey = lambda img: (np.ptp(img.astype(int), -1) < 12) & (img.max(-1) < 200)
        assert grey(with_floor).sum() > 3000 and grey(without).sum() < 0.1 * grey(with_floor).sum()
    finally:
        viewer.close()
        page.goto(session[1].url)


def test_play_advances_the_frames_and_pause_stops_them(session):
    """`play` steps the frame slider at the run's frame rate (and the page follows); `pause` stops it where it is."""
    page, viewer, _ = session
    settled(page, viewer, show(viewer, 0, "full"))
    page.get_by_role("button", name="play").click()
    page.wait_for_timeout(1200)
    page.get_by_role("button", name="pause").click()
    deadline = time.monotonic() + 10  # the click reaches the server a moment after the browser sent it
    while viewer.play.label != "play" and time.monotonic() < deadline:
        time.sleep(0.02)
    assert viewer.play.label == "play"
    stopped = int(viewer.frame.value)
    played = {state[0] for _, state, _, _ in viewer.pushed}
    # the loop wraps after the last frame, so where it stops may be frame 0 again: what proves play is the frames
    # pushed on the way, and that the frame it stopped on is one of them
    assert len(played) >= 3 and stopped in played, (stopped, played)
    page.wait_for_timeout(600)
    assert int(viewer.frame.value) == stopped
    show(viewer, 0, "full")


def test_band_highlight_fades_the_object(session):
    """`band & interfaces`, ticked in the browser, fades everything outside the fracture band toward light grey
    (`panels.colors`): the red block's red drops to 0.35 of its saturation over a light base."""
    page, viewer, _ = session
    before = settled(page, viewer, show(viewer, 2, "full"))
    page.get_by_text("band & interfaces").click()
    after = settled(page, viewer, (2, ("full",), "scene", True, True))
    assert viewer.highlight.value is True
    left = lambda img: img[ink(img) & (np.arange(img.shape[1]) < columns(ink(img)).min() + 40)[None, :]]
    sat = lambda px: float(np.median(px.max(-1).astype(int) - px.min(-1)))
    assert sat(left(after)) < 0.5 * sat(left(before))
    page.get_by_text("band & interfaces").click()
    settled(page, viewer, (2, ("full",), "scene", False, True))
