"""The viewer's run record (`fracture_gs.viewer.format`, `record`, `store`) and the splat buffers made from it
(`panels`): what render-sim writes is what the viewer reads back, within the stated quantisation; a run folder
that cannot be shown is one sentence saying why; a run cut short opens with the frames it has."""

from __future__ import annotations

import json

import numpy as np
import pytest
from viewutil import make_run

from fracture_gs.errors import ViewError
from fracture_gs.viewer import format as fmt
from fracture_gs.viewer import panels
from fracture_gs.viewer.record import interface_flags
from fracture_gs.viewer.store import open_run


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    return make_run(tmp_path_factory.mktemp("run"), frames=4, per_axis=8)


def test_frame_record_round_trip_within_the_stated_quantisation():
    """A centre comes back within half a quantisation step (extent / 65535 / 2) of the frame's box, a covariance
    within float16's relative precision (2⁻¹¹) in units of cov_unit, and the record is 48 + 18 N bytes."""
    rng = np.random.default_rng(1)
    n = 500
    means = rng.uniform(-0.3, 1.7, (n, 3))
    a = rng.normal(size=(n, 3, 3)) * 0.004
    cov = a @ a.transpose(0, 2, 1) + np.eye(3) * 1e-6  # [n,3,3] SPD, millimetre scale
    unit = 2e-5
    buf = fmt.encode_frame(7, 2, 0.35, means, fmt.covariance_triu(cov), unit)
    assert len(buf) == fmt.frame_bytes(n) == 48 + 18 * n
    rec = fmt.decode_frame(buf, n)
    assert (rec["frame"], rec["epoch"]) == (7, 2) and rec["time"] == pytest.approx(0.35)
    step = (means.max(0) - means.min(0)) / 65535
    assert (np.abs(rec["means"] - means) <= step / 2 + 1e-6).all()
    got = rec["cov"].astype(np.float64) * unit
    want = fmt.covariance_triu(cov)
    assert (np.abs(got - want) <= np.abs(want) * 2**-11 + 6e-8 * unit).all()
    with pytest.raises(ValueError):
        fmt.decode_frame(b"XXXX" + buf[4:], n)


def test_epoch_record_round_trip_and_clipping():
    """Colours become uint8 (rounded), flags and fragment ids come back exactly; ids past int16 are clipped."""
    rgb = np.array([[0.0, 0.5, 1.0], [0.2, 0.3, 1.4]])
    flags = np.array([fmt.DRAWN | fmt.BAND, fmt.INTERIOR], np.uint8)
    rec = fmt.decode_epoch(fmt.encode_epoch(3, 9, rgb, flags, np.array([-1, 70000])), 2)
    assert (rec["epoch"], rec["first_frame"]) == (3, 9)
    assert rec["rgb"].tolist() == [[0, 128, 255], [51, 76, 255]]
    assert rec["flags"].tolist() == flags.tolist() and rec["fragment"].tolist() == [-1, 32767]


def test_interface_flags_are_band_gaussians_facing_another_fragment():
    """A band Gaussian is an interface when a band Gaussian of another fragment lies within the radius: checked
    against all pairs by brute force."""
    rng = np.random.default_rng(4)
    means = rng.uniform(0, 1, (400, 3))
    fragment = (means[:, 0] > 0.5).astype(np.int64)
    fragment[:10] = -1
    band = np.abs(means[:, 0] - 0.5) < 0.15
    got = interface_flags(means, fragment, band, 0.08)
    d = np.linalg.norm(means[:, None] - means[None], axis=-1)
    ok = band & (fragment >= 0)
    want = ok & ((d < 0.08) & ok[None, :] & (fragment[None, :] != fragment[:, None])).any(1)
    assert got.tolist() == want.tolist() and 0 < want.sum() < ok.sum()


def test_writer_keeps_a_new_epoch_only_when_the_topology_or_colours_change(run):
    """`full` fractures once (frame 1): two epoch records (before, after); `baseline` never does: one. Every
    frame of each variant is readable and carries the fragment ids of its epoch."""
    view = open_run(run)
    n = view.n
    for variant, epochs in (("full", 2), ("baseline", 1)):
        assert (run / "view" / f"{variant}.epochs").stat().st_size == epochs * fmt.epoch_bytes(n)
        assert view.counts[variant] == 5
    assert np.unique(view.frame("full", 0).fragment).tolist() == [-1]
    assert np.unique(view.frame("full", 3).fragment).tolist() == [0, 1]
    assert (view.frame("full", 3).flags & fmt.BAND).any() and not (view.frame("baseline", 3).flags & fmt.BAND).any()
    left = view.frame("full", 0).means[:, 0] < 0.5
    moved = view.frame("full", 4).means[left, 0] - view.frame("full", 0).means[left, 0]
    assert moved == pytest.approx(np.full(left.sum(), -0.12), abs=2e-5)  # 4 frames × 3 cm to the left


def test_a_run_cut_short_opens_with_the_frames_it_has(run, tmp_path):
    """Ctrl-C mid-write leaves a partial last record: the reader drops it and says which variant is short; a
    frame whose epoch record was cut is dropped too."""
    import shutil

    cut = tmp_path / "cut"
    shutil.copytree(run, cut)
    frames = cut / "view" / "full.frames"
    size = fmt.frame_bytes(open_run(run).n)
    frames.write_bytes(frames.read_bytes()[: 3 * size + 100])
    view = open_run(cut)
    assert view.counts == {"baseline": 5, "full": 3} and view.frames == 5
    assert view.notes == ["full: 3 of 5 frames (the run was cut short or the variant diverged)"]
    epochs = cut / "view" / "full.epochs"
    epochs.write_bytes(epochs.read_bytes()[:-1])  # the second epoch (from frame 1 on) cut
    assert open_run(cut).counts["full"] == 1
    assert open_run(cut).frame("full", 4).frame == 0  # past its end, a variant shows its last frame


@pytest.mark.parametrize(
    "damage, words",
    [
        ("empty", "not a render-sim output folder"),
        ("old run", "written by a fracture-gs without the viewer's record"),
        ("newer", "view format 2, this fracture-gs reads 1); upgrade fracture-gs"),
        ("garbage index", "index.json is damaged"),
        ("no frames", "stopped before its first frame was drawn"),
        ("missing folder", "no such folder"),
    ],
)
def test_a_folder_that_cannot_be_shown_is_one_sentence(run, tmp_path, damage, words):
    """Each way a folder can fail to be viewable raises ViewError with one sentence that says why and what to do
    (no traceback from deep inside, no half-open viewer)."""
    import shutil

    folder = tmp_path / "r"
    if damage == "empty":
        folder.mkdir()
    elif damage == "old run":
        folder.mkdir()
        (folder / "summary.json").write_text("{}")
    elif damage != "missing folder":
        shutil.copytree(run, folder)
        index = folder / "view" / "index.json"
        if damage == "newer":
            index.write_text(json.dumps({**json.loads(index.read_text()), "version": 2}))
        elif damage == "garbage index":
            index.write_text("{not json")
        else:
            for f in (folder / "view").glob("*.frames"):
                f.write_bytes(b"")
    with pytest.raises(ViewError) as err:
        open_run(folder)
    text = str(err.value)
    assert words in text and "\n" not in text and text.count(". ") == 0


def test_splat_buffer_packs_what_the_browser_reads(run):
    """The packed buffer is viser's layout: centre (float32 ×3, local = world / s), a zero word, the covariance's
    upper triangle (float16 ×6, as recorded), RGBA; only drawn Gaussians are packed."""
    view = open_run(run)
    frame = view.frame("full", 2)
    frame.flags = frame.flags.copy()
    frame.flags[:5] &= ~np.uint8(fmt.DRAWN)  # five hidden Gaussians
    s = 0.01
    buf = panels.frame_buffer(frame, view.static["opacity"], s)
    assert buf.shape == (view.n - 5, 8) and buf.dtype == np.uint32
    assert np.allclose(buf[:, :3].view(np.float32) * s, frame.means[5:], atol=1e-6)
    assert (buf[:, 3] == 0).all()
    assert (buf[:, 4:7].copy().view(np.float16) == frame.cov[5:]).all()
    rgba = buf[:, 7:8].copy().view(np.uint8)
    assert (rgba[:, :3] == frame.rgb[5:]).all() and (rgba[:, 3] == view.static["opacity"][5:]).all()


def test_preview_keeps_every_kth_gaussian_widened():
    """A preview of budget B out of M drawn keeps every k-th (k = ⌈M/B⌉) with covariance × k^(2/3) (σ × k^(1/3));
    budget 0, or M ≤ B, keeps every Gaussian as recorded."""
    from fracture_gs.viewer.store import Frame

    n = 1000
    frame = Frame(
        0,
        0.0,
        np.zeros((n, 3), np.float32),
        np.full((n, 6), 0.5, np.float16),
        np.zeros((n, 3), np.uint8),
        np.full(n, fmt.DRAWN, np.uint8),
        np.zeros(n, np.int16),
        (np.zeros(3), np.ones(3)),
    )
    opacity = np.full(n, 255, np.uint8)
    assert len(panels.frame_buffer(frame, opacity, 1.0, budget=0)) == n
    assert len(panels.frame_buffer(frame, opacity, 1.0, budget=n)) == n
    buf = panels.frame_buffer(frame, opacity, 1.0, budget=300)
    assert len(buf) == 250  # k = 4
    assert buf[:, 4:7].copy().view(np.float16)[0, 0] == pytest.approx(0.5 * 4 ** (2 / 3), rel=1e-3)


def test_fragment_colours_and_band_highlight():
    """Colour by fragment gives each fragment its own hue and leaves unbroken Gaussians (−1) their colour; the
    highlight paints band Gaussians amber, interfaces red (interface wins), and fades the rest toward grey."""
    from fracture_gs.viewer.store import Frame

    rgb = np.array([[200, 0, 0]] * 4, np.uint8)
    flags = np.array([fmt.DRAWN, fmt.DRAWN | fmt.BAND, fmt.DRAWN | fmt.BAND | fmt.INTERFACE, fmt.DRAWN], np.uint8)
    frame = Frame(0, 0.0, np.zeros((4, 3), np.float32), np.zeros((4, 6), np.float16), rgb, flags,
                  np.array([0, 1, 2, -1], np.int16), (np.zeros(3), np.ones(3)))  # fmt: skip
    by_fragment = panels.colors(frame, "fragment", False)
    assert len({tuple(np.round(c, 3)) for c in by_fragment[:3]}) == 3
    assert by_fragment[3] == pytest.approx(rgb[3] / 255)
    lit = panels.colors(frame, "scene", True)
    assert lit[1] == pytest.approx(panels.BAND_RGB) and lit[2] == pytest.approx(panels.INTERFACE_RGB)
    assert lit[0] == pytest.approx(0.35 * np.array([200 / 255, 0, 0]) + 0.52)
    with pytest.raises(ValueError, match="colour mode"):
        panels.colors(frame, "rainbow", False)
