"""Bad input, round six (issue 34, item 5): what a new user's probes still found (docs/probes-round6.md). Each
refusal is one sentence naming the argument or flag and the fix; each test fails on the code before the fix, and
the "still" tests guard the refusals against being wider than the bad value."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch
from badinput import one_line

from fracture_gs.errors import ArgumentError, ConfigError, OutputError, PlyError, RenderError
from fracture_gs.io.config import config_from_dict, load_config
from fracture_gs.io.config.overrides import apply_overrides
from fracture_gs.io.detect import detect_format
from fracture_gs.io.formats import write_gaussians
from fracture_gs.io.outputs import output_dir
from fracture_gs.io.ply import save_ply


@pytest.mark.parametrize("byte", [b"\x01", b"\x7f"])
def test_a_splat_of_control_bytes_is_named_a_splat_not_text(tmp_path, byte):
    """Rule: bytes 0x01-0x1f and 0x7f are binary data; a .splat of them was called "text (first line '\\x01...')".
    A cut .splat now gets the .splat sentence (32-byte rows)."""
    p = tmp_path / "a.splat"
    p.write_bytes(byte * 100)
    with pytest.raises(PlyError) as info:
        detect_format(p)
    msg = one_line(info.value)
    assert "is text" not in msg and "32-byte rows" in msg, msg


def test_still_a_text_file_is_called_text(tmp_path):
    """The neighbouring good case: a real text file (tabs and newlines) is still named text."""
    p = tmp_path / "notes.splat"
    p.write_bytes(b"hello\tworld\n" * 9)
    with pytest.raises(PlyError) as info:
        detect_format(p)
    assert "is text" in one_line(info.value)


def test_read_cameras_of_none_is_an_argument_error():
    """Rule: read_cameras takes a path; None raised pathlib's TypeError."""
    from fracture_gs.capture.fit import read_cameras

    with pytest.raises(ArgumentError) as info:
        read_cameras(None)
    assert "read_cameras: path" in one_line(info.value)


@pytest.mark.parametrize("resolution", [(64,), (64, 48, 3), (64.5, 48), (True, 48)])
def test_apply_overrides_refuses_a_resolution_that_is_not_a_pair_of_ints(resolution):
    """Rule: a resolution pair is two whole numbers: (64,) raised a bare ValueError and (64.5, 48) was cut to 64."""
    with pytest.raises(ConfigError) as info:
        apply_overrides(load_config("bread"), resolution=resolution)
    assert "resolution" in one_line(info.value)


def test_still_apply_overrides_takes_a_resolution_pair():
    """The neighbouring good value: a (w, h) list or tuple of ints still sets the image size."""
    cfg = apply_overrides(load_config("bread"), resolution=[64, 48])
    assert (cfg.render.width, cfg.render.height) == (64, 48)


def test_apply_overrides_of_a_name_is_an_argument_error():
    """Rule: apply_overrides takes a SceneConfig; a name raised AttributeError from inside."""
    with pytest.raises(ArgumentError) as info:
        apply_overrides("bread", frames=2)
    assert "apply_overrides: cfg" in one_line(info.value)


def _img(h=4, w=4):
    return np.zeros((h, w, 3), np.uint8)


@pytest.mark.parametrize(
    "call",
    [
        lambda R: R.side_by_side([]),
        lambda R: R.side_by_side([_img()], captions=["a", "b"]),
        lambda R: R.grid([[]]),
        lambda R: R.caption(_img(), 5),
        lambda R: R.caption(_img(), "x", position="left"),
        lambda R: R.deform_covariances(torch.eye(2).repeat(3, 1, 1), torch.eye(3).repeat(3, 1, 1)),
        lambda R: R.deform_covariances(torch.eye(3).repeat(2, 1, 1), torch.eye(3).repeat(3, 1, 1)),
    ],
    ids=["no-images", "captions", "empty-grid", "caption-int", "caption-left", "F-2x2", "F-count"],
)
def test_render_helpers_refuse_bad_arguments_with_a_render_error(call):
    """Rule: the composing helpers and deform_covariances raise RenderError naming the argument; before they raised
    a bare ValueError, OpenCV's error, torch's RuntimeError, or (position='left') drew the bar below."""
    import fracture_gs.render as R

    with pytest.raises(RenderError) as info:
        call(R)
    one_line(info.value)


def test_still_render_helpers_work_on_good_arguments():
    """The neighbouring good values: captions top and bottom, Σ = F Σ⁰ Fᵀ of a uniform stretch by 2 is 4 Σ⁰."""
    import fracture_gs.render as R

    top, bottom = R.caption(_img(8, 8), "x", position="top"), R.caption(_img(8, 8), "x", position="bottom")
    assert top.shape == bottom.shape and not np.array_equal(top, bottom)
    cov = R.deform_covariances(2.0 * torch.eye(3).repeat(2, 1, 1), torch.eye(3).repeat(2, 1, 1))
    assert torch.allclose(cov, 4.0 * torch.eye(3).repeat(2, 1, 1))


def test_an_uncreatable_out_folder_is_refused_in_one_ended_sentence(tmp_path):
    """Rule: every --out refusal is one sentence ending in a full stop (it had none)."""
    blocker = tmp_path / "f"
    blocker.write_text("x")
    with pytest.raises(OutputError) as info:
        output_dir(Path("/proc/no/such"))
    one_line(info.value)
    with pytest.raises(OutputError) as info:
        output_dir(blocker)
    one_line(info.value)


def _gs(n: int = 20):
    from fracture_gs.io.gaussian_set import GaussianSet

    g = torch.Generator().manual_seed(0)
    return GaussianSet(
        means=torch.rand(n, 3, generator=g),
        quats=torch.nn.functional.normalize(torch.randn(n, 4, generator=g), dim=1),
        scales=torch.full((n, 3), 0.02),
        opacities=torch.full((n,), 0.5),
        sh=torch.zeros(n, 1, 3),
    )


@pytest.mark.parametrize("name", ["x.spz", "x.splat", "x.compressed.ply", "x.ksplat"])
def test_save_ply_refuses_a_name_of_another_format(tmp_path, name):
    """Rule: save_ply writes a 3DGS PLY; under an .spz (or .splat, .compressed.ply, .ksplat) name, viewers that go
    by the name misread it. Before, the file was written without a word."""
    with pytest.raises(PlyError) as info:
        save_ply(_gs(), tmp_path / name)
    assert "save_ply" in one_line(info.value) and "write_gaussians" in str(info.value)
    assert not (tmp_path / name).exists()


@pytest.mark.parametrize(("name", "fmt"), [("y.ply", "spz"), ("y.spz", "splat"), ("y.compressed.ply", "ply")])
def test_write_gaussians_refuses_a_name_that_names_another_format(tmp_path, name, fmt):
    """Rule: a file name whose suffix names one format and fmt another is refused (an SPZ was written as y.ply)."""
    with pytest.raises(PlyError) as info:
        write_gaussians(_gs(), tmp_path / name, fmt)
    assert "fmt" in one_line(info.value)
    assert not (tmp_path / name).exists()


@pytest.mark.parametrize(
    ("name", "fmt"), [("a.ply", "ply"), ("b.ply", "compressed-ply"), ("c", "spz"), ("d.bin", "splat")]
)
def test_still_writers_take_matching_or_neutral_names(tmp_path, name, fmt):
    """The neighbouring good values: a matching suffix, a compressed PLY under .ply (a PLY still), or a name with no
    splat suffix are written and read back with all their Gaussians."""
    from fracture_gs.io.formats import read_gaussians

    path = write_gaussians(_gs(), tmp_path / name, fmt)
    assert len(read_gaussians(path)[0]) == 20


def test_save_ply_refuses_normals_that_are_not_a_bool(tmp_path):
    """Rule: normals is True, False or None; 'yes' (truthy) was taken as True without a word."""
    with pytest.raises(ArgumentError) as info:
        save_ply(_gs(), tmp_path / "n.ply", normals="yes")
    assert "normals" in one_line(info.value)


@pytest.mark.parametrize(("value", "meant"), [("y", "+y"), ("+Y", "+y"), ("Z", "+z"), ("PULL", "pull")])
def test_a_choice_in_another_case_or_without_its_sign_suggests_the_one_meant(value, meant):
    """Rule: capture.up = 'y' suggested '-y' (difflib's nearest); a choice typed in capitals or without its '+'
    now suggests the choice it spells."""
    key = "capture.load" if meant == "pull" else "capture.up"
    doc = {"extends": "capture", "scene": "scene.ply", "capture": {key.split(".")[1]: value}}
    with pytest.raises(ConfigError) as info:
        config_from_dict(doc, "probe.toml")
    assert f"did you mean {meant!r}?" in str(info.value) and key in str(info.value), str(info.value)


def test_fuzz_writer_names_and_formats(tmp_path_factory):
    """Property over the writers' family of name rules: for any file stem, splat suffix (or none) and fmt,
    write_gaussians writes exactly when the suffix names no format, the same one, or `.ply` for a compressed PLY
    (a PLY still), and the file then reads back with every Gaussian; otherwise it is one PlyError sentence naming
    fmt and nothing is written."""
    from fuzzutil import fuzz_settings
    from hypothesis import given
    from hypothesis import strategies as st

    from fracture_gs.io.formats import FORMATS, read_gaussians

    gs = _gs(12)
    root = tmp_path_factory.mktemp("names")
    suffixes = ["", ".ply", ".compressed.ply", ".splat", ".spz", ".ksplat", ".bin", ".PLY", ".Spz"]
    named = {".ply": "ply", ".compressed.ply": "compressed-ply", ".splat": "splat", ".spz": "spz", ".ksplat": "ksplat"}

    @fuzz_settings(40)
    @given(
        stem=st.text(alphabet="abcxyz_-0", min_size=1, max_size=8),
        suffix=st.sampled_from(suffixes),
        fmt=st.sampled_from(FORMATS),
    )
    def check(stem, suffix, fmt):
        path = root / f"{stem}{suffix}"
        path.unlink(missing_ok=True)
        says = named.get(suffix.lower())
        if says in (None, fmt) or (fmt == "compressed-ply" and says == "ply"):
            assert len(read_gaussians(write_gaussians(gs, path, fmt))[0]) == 12
        else:
            with pytest.raises(PlyError) as info:
                write_gaussians(gs, path, fmt)
            assert "fmt" in one_line(info.value) and not path.exists()

    check()


@pytest.mark.parametrize(
    ("flag", "value"), [("--steps", 10**9), ("--warmup", 100_001), ("--trials", 1_001), ("--placements", 5_000)]
)
def test_bench_refuses_a_sample_size_no_run_can_finish(capsys, flag, value):
    """Rule: bench --steps 10**9 ran for ever (a hang, no word); the substeps and sample counts now have a ceiling,
    refused by the parser (exit 2) before any device is looked at."""
    from fracture_gs.cli import main

    assert main(["bench", flag, str(value), "--device", "tpu"]) == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert f"argument {flag}" in err and "is more than" in err, err


def test_still_bench_takes_its_ceiling(capsys):
    """The neighbouring good value: --steps 100000 passes the parser (the run then stops at the bad --device)."""
    from fracture_gs.cli import main

    assert main(["bench", "--steps", "100000", "--device", "tpu"]) == 2
    assert "--device 'tpu'" in capsys.readouterr().err
