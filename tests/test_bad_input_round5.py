"""Bad input, round five (issue 34, item 5): capture files, config dicts and Python API values a new user's probes
still found getting through (docs/probes-round5.md). Each refusal is one sentence naming the file, key or argument
and the fix; each test fails on the code before the fix, and the "still" tests guard the refusals against being
wider than the bad value."""

from __future__ import annotations

import gzip
import struct
from pathlib import Path

import numpy as np
import pytest
import torch
from badinput import one_line

from fracture_gs.errors import ArgumentError, ConfigError, PlyError, SceneError, SimulationError
from fracture_gs.io.config import config_from_dict, dump_config, load_config
from fracture_gs.io.formats import read_gaussians, write_gaussians
from fracture_gs.io.gaussian_set import GaussianSet
from fracture_gs.io.ply import load_ply

pytestmark = pytest.mark.usefixtures("one_thread")


def gaussians(n: int = 300, seed: int = 0) -> GaussianSet:
    """n Gaussians in a unit box, degree-1 SH (the compressed PLY then carries an sh element)."""
    g = torch.Generator().manual_seed(seed)
    return GaussianSet(
        means=torch.rand(n, 3, generator=g),
        quats=torch.nn.functional.normalize(torch.randn(n, 4, generator=g), dim=1),
        scales=0.01 + 0.02 * torch.rand(n, 3, generator=g),
        opacities=0.2 + 0.7 * torch.rand(n, generator=g),
        sh=0.3 * torch.randn(n, 4, 3, generator=g),
    )


@pytest.fixture(scope="module")
def files(tmp_path_factory) -> dict:
    """One good file of each quantised format."""
    root = tmp_path_factory.mktemp("r5")
    gs = gaussians()
    out = {}
    for fmt, suffix in (("compressed-ply", ".compressed.ply"), ("spz", ".spz"), ("splat", ".splat")):
        out[fmt] = write_gaussians(gs, root / f"scene{suffix}", fmt)
    return out


def _edited(src: Path, name: str, data: bytes) -> Path:
    p = src.with_name(name)
    p.write_bytes(data)
    return p


# ---------------------------------------------------------------- compressed PLY


@pytest.mark.parametrize("fmt", ["ascii", "binary_big_endian"])
def test_a_compressed_ply_not_in_little_endian_binary_is_refused(files, fmt):
    """A compressed PLY's packed fields are little-endian words: a header saying ascii or big-endian was read as
    little-endian binary anyway and gave Gaussians built from misread bytes (a silent misread)."""
    raw = files["compressed-ply"].read_bytes()
    bad = _edited(files["compressed-ply"], f"{fmt}.compressed.ply", raw.replace(b"binary_little_endian", fmt.encode()))
    with pytest.raises(PlyError) as e:
        read_gaussians(bad)
    assert fmt in one_line(e.value) and "binary_little_endian" in str(e.value)


def test_a_compressed_ply_whose_sh_rows_disagree_with_its_gaussians_is_refused(files):
    """The sh element holds one row per Gaussian; a count of 100 for 300 Gaussians was read without a word."""
    raw = files["compressed-ply"].read_bytes()
    bad = _edited(files["compressed-ply"], "sh100.compressed.ply", raw.replace(b"element sh 300", b"element sh 100"))
    with pytest.raises(PlyError) as e:
        read_gaussians(bad)
    assert "100 rows" in one_line(e.value) and "300 Gaussians" in str(e.value)


def test_a_good_compressed_ply_still_reads(files):
    """The two checks leave a SuperSplat-layout file alone."""
    gs, dropped, fmt = read_gaussians(files["compressed-ply"])
    assert (len(gs), dropped, fmt) == (300, 0, "compressed-ply")


# ---------------------------------------------------------------- SPZ


def _spz_with(files, name: str, **fields) -> Path:
    raw = gzip.decompress(files["spz"].read_bytes())
    magic, version, n, degree, bits = struct.unpack_from("<IIIBB", raw)
    values = {"version": version, "n": n, "degree": degree, **fields}
    head = struct.pack("<IIIBB", magic, values["version"], values["n"], values["degree"], bits) + raw[14:16]
    return _edited(files["spz"], name, gzip.compress(head + raw[16:]))


@pytest.mark.parametrize(
    "fields, name",
    [({"n": 10}, "count10.spz"), ({"version": 2}, "v2.spz"), ({"degree": 0}, "deg0.spz")],
)
def test_an_spz_whose_header_disagrees_with_its_data_is_refused(files, fields, name):
    """gsply decodes the header's count and degree from whatever bytes follow: a count of 10 over 300 Gaussians'
    data, a v3 file relabelled v2 (3-byte rotations) or a wrong SH degree came back as Gaussians assembled from
    other fields' bytes. The gzip payload must be exactly what the header describes."""
    with pytest.raises(PlyError) as e:
        read_gaussians(_spz_with(files, name, **fields))
    assert "header and data disagree" in one_line(e.value)


def test_a_good_spz_still_reads(files):
    """The exact-size check accepts the writer's own v3 file (and so every consistent one)."""
    gs, dropped, fmt = read_gaussians(files["spz"])
    assert (len(gs), dropped, fmt) == (300, 0, "spz")


# ---------------------------------------------------------------- .splat


def test_a_cut_off_splat_names_its_32_byte_rows(files):
    """A .splat cut inside a row was called 'binary data in no format recognised; pass a splat file', to a user
    who had passed one: the message now says its size is no multiple of the 32-byte row."""
    raw = files["splat"].read_bytes()
    with pytest.raises(PlyError) as e:
        read_gaussians(_edited(files["splat"], "cut.splat", raw[:-16]))
    assert "no multiple of 32" in one_line(e.value)


def test_a_damaged_splat_says_how_many_rows_decode(files):
    """Half the rows with NaN positions: the file is a damaged .splat, and the message says what share decodes."""
    rows = np.frombuffer(files["splat"].read_bytes(), np.uint8).reshape(-1, 32).copy()
    rows[::2, 0:12] = np.frombuffer(np.full(3, np.nan, "<f4").tobytes(), np.uint8)
    with pytest.raises(PlyError) as e:
        read_gaussians(_edited(files["splat"], "half.splat", rows.tobytes()))
    assert "50%" in one_line(e.value) and ".splat" in str(e.value)


# ---------------------------------------------------------------- load_ply, GaussianSet, write_gaussians


def test_load_ply_of_an_spz_names_the_reader_that_takes_it(files):
    """load_ply on a .spz said "'ascii' codec can't decode byte 0x8b"; it now names read_gaussians."""
    with pytest.raises(PlyError) as e:
        load_ply(files["spz"])
    assert "read_gaussians" in one_line(e.value)


def test_load_ply_of_a_missing_file_is_one_ended_sentence(tmp_path):
    """The PLY reader's messages ended without a full stop (one sentence, ended)."""
    with pytest.raises(PlyError) as e:
        load_ply(tmp_path / "nope.ply")
    one_line(e.value)


def test_an_empty_index_list_selects_no_gaussian():
    """subset([]) was refused as 'dtype torch.float32' (torch reads an empty list as float): it selects nothing."""
    assert len(gaussians(20).subset([])) == 0


@pytest.mark.parametrize("fmt", ["spz", "compressed-ply", "splat"])
def test_writing_no_gaussians_in_a_quantised_format_is_refused(tmp_path, fmt):
    """An empty set written as spz or compressed-ply raised numpy's 'zero-size array to reduction operation'; as
    splat it wrote 0 bytes that no reader takes."""
    empty = gaussians(20).subset(torch.zeros(20, dtype=torch.bool))
    with pytest.raises(PlyError) as e:
        write_gaussians(empty, tmp_path / "e.bin", fmt)
    assert "no Gaussians" in one_line(e.value)


# ---------------------------------------------------------------- config dicts, dump_config


@pytest.mark.parametrize("doc", [{1: 2}, {"extends": "bread", "sim": {2: 3}}])
def test_a_config_dict_key_that_is_not_a_string_is_refused(doc):
    """config_from_dict({1: 2}) was a TypeError from difflib's 'did you mean'."""
    with pytest.raises(ConfigError) as e:
        config_from_dict(doc)
    assert "not str" in one_line(e.value)


def test_numpy_numbers_in_a_config_dict_are_numbers():
    """np.int64(3) frames and a numpy gravity were refused as 'not a int64' / 'not a ndarray': they are the
    numbers TOML would have read."""
    cfg = config_from_dict({"extends": "bread", "frames": np.int64(3), "sim": {"gravity": np.array([0.0, 0, -5])}})
    assert cfg.frames == 3 and tuple(cfg.sim.gravity) == (0.0, 0.0, -5.0)


def test_a_numpy_bool_is_still_not_an_integer():
    """The numpy conversion does not widen the rule that a boolean is not a count."""
    with pytest.raises(ConfigError):
        config_from_dict({"extends": "bread", "frames": np.bool_(True)})


def test_dump_config_header_must_be_text():
    """dump_config(cfg, header=5) was an AttributeError ('int' object has no attribute 'splitlines')."""
    with pytest.raises(ArgumentError) as e:
        dump_config(load_config("bread"), header=5)
    assert "header" in one_line(e.value)


# ---------------------------------------------------------------- assets, Simulator, resolve, pipeline


def test_a_seed_beyond_64_bits_is_refused():
    """assets.build(seed=2**70) was torch's 'Overflow when unpacking long long'."""
    from fracture_gs import assets

    with pytest.raises(SceneError) as e:
        assets.build("bread", n=50, seed=2**70)
    assert "seed" in one_line(e.value)
    assert len(assets.build("bread", n=50, seed=2**64 - 1)) > 0  # the largest seed torch takes still builds


def test_an_unknown_simulator_device_is_one_sentence_with_the_fix():
    """'device 'None' is not 'cpu' or 'cuda:N'' gave no fix and no full stop."""
    from fracture_gs.sim.simulator import normalize_device

    with pytest.raises(SimulationError) as e:
        normalize_device(None)
    assert "device='cpu'" in one_line(e.value)


def test_resolve_of_a_built_in_scene_names_prepare_scene():
    """resolve(bread's config) said 'bread: no such file; ... use a built-in scene: bread, ...'."""
    from fracture_gs.capture.scene import resolve

    with pytest.raises(ArgumentError) as e:
        resolve(load_config("bread"))
    assert "prepare_scene" in one_line(e.value)


def test_a_material_property_the_scene_lacks_is_one_sentence(monkeypatch, tmp_path):
    """'material_property ... is not a vertex property of the PLY; available: none' had no fix and no full stop."""
    import fracture_gs.capture.scene as scene
    from fracture_gs.pipeline import prepare_scene

    cfg = config_from_dict({"extends": "capture", "scene": str(tmp_path / "s.ply"), "material_property": "label"})
    monkeypatch.setattr(scene, "resolve", lambda c, device="cpu": scene.Capture(c, gaussians(20), None, None, []))
    with pytest.raises(SimulationError) as e:
        prepare_scene(cfg)
    assert "material_property" in one_line(e.value)


# ---------------------------------------------------------------- the CFL bound at load


def test_a_modulus_whose_cfl_substeps_exceed_the_cap_is_refused_at_load():
    """E = 1e30 Pa (a wave speed of 1e13 m/s) was accepted by validate and refused only by the first frame, after
    the scene was built, as 'needs 131266027842848 substeps ..., over sim.max_substeps_per_frame' (no fix)."""
    with pytest.raises(ConfigError) as e:
        config_from_dict({"extends": "bread", "material": {"E": 1e30}})
    assert "material.E" in one_line(e.value) and "max_substeps_per_frame" in str(e.value)


def test_a_stiff_material_map_entry_is_named():
    """The bound is checked per material_map entry too (a stiff label's wave speed sets the substep)."""
    doc = {"extends": "bread", "material_map": [{"label": 1, "E": 1e30}]}
    with pytest.raises(ConfigError) as e:
        config_from_dict(doc)
    assert "material_map[0].E" in one_line(e.value)


def test_the_built_in_configs_still_load_under_the_cfl_bound():
    """Every built-in config, including the stiff ones of the paper's tables, passes the new bound."""
    from fracture_gs.io.config.files import CONFIG_DIR

    names = sorted(p.stem for p in Path(CONFIG_DIR).glob("*.toml"))
    assert len(names) > 10
    for name in names:
        load_config(name)


# ---------------------------------------------------------------- a load replaces the config's velocity and gravity


@pytest.mark.slow
def test_a_load_that_replaces_initial_velocity_and_gravity_says_so(tmp_path):
    """capture.load = "pull" with initial_velocity = [0, 0, -5] and gravity [0, 0, -20]: the load's plan wrote its
    own over both without a word; the load's note now names them (capture.load = "none" keeps them)."""
    from trainer_ply import write_trainer_ply

    from fracture_gs.capture.scene import resolve

    ply, _ = write_trainer_ply(tmp_path / "m", n=800, cameras=True)
    doc = {
        "extends": "capture",
        "scene": str(ply),
        "initial_velocity": [0.0, 0.0, -5.0],
        "sim": {"gravity": [0.0, 0.0, -20.0]},
        "capture": {"load": "pull"},
    }
    notes = " ".join(resolve(config_from_dict(doc)).notes)
    assert "initial_velocity [0.0, 0.0, -5.0]" in notes and "sim.gravity [0.0, 0.0, -20.0]" in notes
    doc["capture"]["load"] = "none"
    kept = resolve(config_from_dict(doc))
    assert tuple(kept.cfg.initial_velocity) == (0.0, 0.0, -5.0) and "not used" not in " ".join(kept.notes)


# ---------------------------------------------------------------- init --out


def test_init_refuses_an_out_that_is_not_a_toml(tmp_path, capsys):
    """`init scene.ply --out x.ply` wrote the TOML under x.ply (render-sim then read it as a broken scene);
    refused before the scene is resolved, naming --out and a .toml name."""
    from fracture_gs.cli import main

    ply = write_gaussians(gaussians(50), tmp_path / "scene.ply", "ply")
    code = main(["init", str(ply), "--out", str(tmp_path / "x_out.ply")])
    err = capsys.readouterr().err.strip()
    assert code == 2 and "\n" not in err and "--out" in err and "x_out.toml" in err, (code, err)
    assert not (tmp_path / "x_out.ply").exists()


# ---------------------------------------------------------------- config ranges, FractureSim.forward


@pytest.mark.parametrize(
    "doc, key",
    [
        ({"render": {"fps": 100000}}, "render.fps"),  # written into the videos as is
        ({"sim": {"gravity": [0.0, 0.0, 1e300]}}, "sim.gravity"),  # diverged in frame 1 (exit 1) after the build
        ({"sim": {"gravity": [0.0, 0.0, -1e6]}}, "sim.gravity"),
    ],
)
def test_a_frame_rate_or_gravity_no_user_can_mean_is_refused(doc, key):
    """Playback above 1000 fps and gravity above 10,000 m/s² (about 1,000 g) were accepted."""
    with pytest.raises(ConfigError) as e:
        config_from_dict({"extends": "bread", **doc})
    assert key in one_line(e.value)


def test_the_neighbouring_frame_rates_and_gravities_still_load():
    """The bounds are inclusive and leave every plausible value alone."""
    cfg = config_from_dict({"extends": "bread", "render": {"fps": 1000}, "sim": {"gravity": [0.0, 0.0, -9999.0]}})
    assert cfg.render.fps == 1000 and cfg.sim.gravity[2] == -9999.0


def test_a_huge_frame_over_substep_ratio_is_shown_short():
    """frame_dt = 1e300 printed a 300-digit substep count in its message; it is now shown in three digits."""
    with pytest.raises(ConfigError) as e:
        config_from_dict({"extends": "bread", "frame_dt": 1e300})
    assert "max_substeps_per_frame" in one_line(e.value) and len(str(e.value)) < 200


def test_fracture_sim_called_with_a_gaussian_set_names_the_fix():
    """sim(gs) raised Python's 'missing 2 required positional arguments: opacities and sh'."""
    from fracture_gs import FractureSim

    with pytest.raises(ArgumentError) as e:
        FractureSim(load_config("bread"))(gaussians(20))
    assert "sim.frames(gs)" in one_line(e.value)
