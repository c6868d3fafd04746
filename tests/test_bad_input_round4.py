"""Bad input, round four (issue 34, item 5): config keys, captures, cameras.json and sweep specs and caches that a
new user's probes still found getting through, each refused where it enters in one sentence naming the key and
the fix (docs/probes-round4.md lists every probe). Each test fails on the code before the fix. The CLI flags and
the Python API are in tests/test_bad_input_round4_cli_api.py."""

from __future__ import annotations

import json
import os
import threading
import time

import pytest
import torch
from badinput import capture_doc, one_line
from trainer_ply import write_trainer_ply

from fracture_gs.capture.scene import resolve
from fracture_gs.errors import ConfigError, OutputError, SceneError
from fracture_gs.io.config import config_from_dict

pytestmark = pytest.mark.usefixtures("one_thread")


def refused(doc: dict, key: str) -> str:
    with pytest.raises(ConfigError) as info:
        config_from_dict(doc, "probe.toml")
    msg = one_line(info.value)
    assert key in msg and "no effect" in msg, msg
    return msg


# ---------------------------------------------------------------- keys the rest of the config turns off

BUILTIN = [("load", "pull"), ("size", 0.3), ("material", "wood"), ("cells_across", 16), ("ground", "none")]


@pytest.mark.parametrize("key, value", BUILTIN, ids=[k for k, _ in BUILTIN])
def test_a_capture_key_on_a_built_in_scene_is_refused(key, value):
    """Rule: [capture] prepares a captured scene (a splat file); on a built-in scene (extends = "bread") every
    [capture] key other than its default does nothing, so it is a ConfigError naming it (it loaded as valid)."""
    refused({"extends": "bread", "capture": {key: value}}, f"capture.{key}")


def test_a_built_in_scene_keeps_its_defaults_and_refuses_a_ply_property():
    """Rule: [capture] at its defaults (as a run's config.toml writes it) still loads on a built-in scene, and
    material_property, which names a PLY vertex property, is refused there (a built-in asset has none)."""
    assert config_from_dict({"extends": "bread", "capture": {"load": "auto"}}).capture.load == "auto"
    refused({"extends": "bread", "material_property": "fgs_label"}, "material_property")


FIT_FALSE = [
    ("load", "pull"),
    ("material", "wood"),
    ("cells_across", 32),
    ("quality", "fine"),
    ("size", 0.3),
    ("min_opacity", 0.2),
    ("camera", "trainer"),
    ("up", "+z"),
    ("outlier_std", 2.0),
    ("ground", "none"),
    ("fill_closing", 3),
    ("max_particles", 5000),
]


@pytest.mark.parametrize("key, value", FIT_FALSE, ids=[k for k, _ in FIT_FALSE])
def test_a_capture_key_beside_fit_false_is_refused(key, value):
    """Rule: capture.fit = false uses the file as written (only the interior fill applies), so any other [capture]
    key set away from its default is refused naming it (each loaded and did nothing)."""
    msg = refused(capture_doc(fit=False, **{key: value}), f"capture.{key}")
    assert "capture.fit = false" in msg


def test_fit_false_alone_and_fit_true_with_the_same_keys_load():
    """Rule (no false refusal): fit = false alone loads, and the same keys load with the fit on; capture.panel =
    "config", which a run's config.toml of a built-in scene or a fit = false capture holds (--resolution wrote it
    there), loads on both."""
    assert config_from_dict(capture_doc(fit=False, panel="config")).capture.fit is False
    assert config_from_dict({"extends": "bread", "capture": {"panel": "config"}}).capture.panel == "config"
    cfg = config_from_dict(capture_doc(**dict(FIT_FALSE[:9])))
    assert (cfg.capture.load, cfg.capture.cells_across, cfg.capture.up) == ("pull", 32, "+z")


TURNED_OFF = [
    ({"outlier_neighbours": 0, "outlier_std": 2.0}, "capture.outlier_std"),
    ({"roi": "sphere", "roi_center": [0, 0, 0], "roi_radius": 1.0, "percentile": 5.0}, "capture.percentile"),
    ({"roi": "all", "percentile": 5.0}, "capture.percentile"),
    ({"up": "-y", "rotation": [[1.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0]]}, "capture.up"),
]


@pytest.mark.parametrize("values, key", TURNED_OFF, ids=[k for _, k in TURNED_OFF])
def test_a_capture_key_another_turns_off_is_refused(values, key):
    """Rule: outlier_std with the outlier removal off (0 neighbours), a percentile beside an ROI that is not the
    automatic one, and an up axis that capture.rotation contradicts (the rotation takes another axis to +z) each
    did nothing; refused naming the key."""
    refused(capture_doc(**values), key)


def test_max_particles_without_a_fill_is_refused():
    """Rule: capture.max_particles is the interior fill's budget; with fill_interior = false it did nothing."""
    doc = capture_doc(max_particles=1000)
    doc["fill_interior"] = False
    refused(doc, "capture.max_particles")


def test_the_combinations_that_act_still_load():
    """Rule (no false refusal): an up axis the rotation agrees with, a box ROI with a percentile (a resolved
    config keeps both: the percentile comes back with roi = "auto"), a trainer view beside camera = "config" (kept
    for the switch back), quality beside cells_across (quality still sets the fill budget) and the fill keys without
    a fill (they steer the automatic Δx) all load."""
    ident = [[1.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0]]
    box = {"roi": "box", "roi_lower": [0, 0, 0], "roi_upper": [1, 1, 1], "percentile": 5.0}
    docs = [capture_doc(up="+z", rotation=ident), capture_doc(**box), capture_doc(camera="config", view=3)]
    docs += [capture_doc(cells_across=32, quality="fine"), {**capture_doc(fill_closing=3), "fill_interior": False}]
    for doc in docs:
        assert config_from_dict(doc).capture is not None


def test_particles_and_preset_on_a_captured_scene_are_refused():
    """Rule: `particles` sizes a built-in asset and `preset` a built-in scene's Δx; on a fitted capture both did
    nothing (the CLI refused the flags, the TOML keys loaded). With fit = false the preset sets Δx and loads."""
    refused({**capture_doc(), "particles": 2000}, "particles")
    refused({**capture_doc(), "preset": "paper"}, "preset")
    assert config_from_dict({**capture_doc(fit=False), "preset": "paper"}).preset == "paper"


VALUES = [
    (capture_doc(cameras_json="cams\x00.json"), "capture.cameras_json"),  # no path holds NUL: OSError at resolve
    ({"extends": "bread", "initial_velocity": [1e30, 0.0, 0.0]}, "initial_velocity"),  # the CFL step underflows
]


@pytest.mark.parametrize("doc, key", VALUES, ids=[k for _, k in VALUES])
def test_a_value_no_run_can_use_is_refused_when_loaded(doc, key):
    """Rule: a cameras.json path with a NUL byte and an initial speed over 10 km/s are refused as the config loads,
    naming the key (the path raised ValueError at resolve; the speed ZeroDivisionError or a diverged run)."""
    with pytest.raises(ConfigError) as info:
        config_from_dict(doc, "probe.toml")
    assert key in one_line(info.value)


def test_a_sweep_spec_given_as_a_config_says_so(tmp_path):
    """Rule: `validate spec.toml` on a sweep spec names it a sweep spec and the command to run (it said "unknown
    key 'accuracy'" and listed the scene keys)."""
    from fracture_gs.io.config import load_config

    spec = tmp_path / "spec.toml"
    spec.write_text('[[accuracy]]\ncase = "bar"\ncells = [8]\ncfl = 0.4\n')
    with pytest.raises(ConfigError) as info:
        load_config(spec)
    assert "sweep spec" in one_line(info.value) and "fracture-gs sweep" in str(info.value)


# ---------------------------------------------------------------- capture: resolve


@pytest.fixture(scope="module")
def small_ply(tmp_path_factory):
    ply, _ = write_trainer_ply(tmp_path_factory.mktemp("round4_capture"), n=400)
    return ply


def test_a_percentile_whose_core_is_empty_is_a_scene_error(small_ply):
    """Rule: capture.percentile = 49 bounds the automatic ROI by the 49th and 51st percentiles per axis, a box that
    holds almost no Gaussian; one SceneError naming the key (it was torch's IndexError from an empty min())."""
    with pytest.raises(SceneError) as info:
        resolve(config_from_dict(capture_doc(str(small_ply), percentile=49.0, up="-y")))
    msg = one_line(info.value)
    assert msg.startswith(f"{small_ply}: ") and "capture.percentile = 49" in msg


def test_a_scene_at_one_point_names_the_file_and_the_fix(tmp_path):
    """Rule: a scene whose Gaussians all sit at one point is one sentence naming the file and a fix (it was "the
    object has no extent after clean-up (...)", naming neither)."""
    from fracture_gs.io.gaussian_set import GaussianSet
    from fracture_gs.io.ply import save_ply

    n = 50
    q = torch.zeros(n, 4)
    q[:, 0] = 1
    ply = tmp_path / "dot.ply"
    gs = GaussianSet(torch.ones(n, 3), q, torch.full((n, 3), 0.02), torch.full((n,), 0.9), torch.zeros(n, 1, 3))
    save_ply(gs, ply)
    with pytest.raises(SceneError) as info:
        resolve(config_from_dict(capture_doc(str(ply), up="-y")))
    msg = one_line(info.value)
    assert msg.startswith(f"{ply}: ") and "capture.fit = false" in msg


def test_a_material_region_that_holds_nothing_is_a_scene_error(small_ply):
    """Rule: a [[capture.regions]] box that holds none of the object's Gaussians changes nothing; it is a SceneError
    naming capture.regions[0] (before, the run went on with a note of "0 Gaussians wood")."""
    region = {"lower": [1e6, 1e6, 1e6], "upper": [1.1e6, 1.1e6, 1.1e6], "material": "wood"}
    with pytest.raises(SceneError) as info:
        resolve(config_from_dict(capture_doc(str(small_ply), up="-y", cells_across=8, regions=[region])))
    assert "capture.regions[0]" in one_line(info.value)


@pytest.mark.slow
def test_replaced_render_settings_are_named_in_the_notes(small_ply):
    """Rule: capture.panel = "auto" and capture.camera = "auto" replace the config's [render] size and
    [render.camera]; a size or camera the config asked for is named in the printed notes (it was replaced
    without a word). The automatic placeholders (640×480, default camera) give no note."""
    doc = capture_doc(str(small_ply), up="-y", cells_across=8, max_particles=300)
    doc["render"] = {"width": 1024, "height": 768, "camera": {"eye": [2.0, 2.0, 2.0], "target": [0.5, 0.5, 0.5]}}
    notes = resolve(config_from_dict(doc)).notes
    assert any("1024×768" in n and "capture.panel" in n for n in notes), notes
    assert any(n.startswith("camera:") and "[render.camera] eye, target" in n for n in notes), notes
    quiet = resolve(config_from_dict(capture_doc(str(small_ply), up="-y", cells_across=8, max_particles=300))).notes
    assert not any("not used" in n for n in quiet), quiet


# ---------------------------------------------------------------- cameras.json


def test_an_image_name_with_a_newline_stays_one_line(tmp_path):
    """Rule: a view's img_name is shown on one line and at most 40 characters in a message (a newline in it split
    the sentence; 5,000 characters buried it)."""
    from fracture_gs.capture.fit import read_cameras

    view = {"img_name": "a\nb" + "x" * 5000, "width": 640, "height": 480, "position": [0, 0, 0], "fx": 0, "fy": 500}
    path = tmp_path / "cameras.json"
    path.write_text(json.dumps([{**view, "rotation": [[1, 0, 0], [0, 1, 0], [0, 0, 1]]}]))
    with pytest.raises(SceneError) as info:
        read_cameras(path)
    msg = one_line(info.value)
    assert "(a bxxx" in msg and len(msg) < 400


# ---------------------------------------------------------------- sweep specs


def spec_file(tmp_path, text: str):
    path = tmp_path / "spec.toml"
    path.write_text(text)
    return path


SCENE = '[[scene]]\nconfig = ["bread"]\nvariant = ["baseline"]\nframes = 2\nparticles = 300\n'
SHADOWED = [
    ('[scene.material]\nE = [1e5]\n[scene.set]\n"material.E" = [3e5]\n', "material.E"),
    ('dt = [1e-4]\n[scene.set]\n"sim.dt" = [2e-4]\n', "sim.dt"),
    ('cfl = [0.3]\n[scene.set]\n"sim.cfl" = [0.2]\n', "sim.cfl"),
    ('[scene.set]\n"frames" = [5, 10]\n', "frames"),
    ('[scene.set]\n"variants" = [["full"]]\n', "variants"),
    ('[scene.set]\n"topology.seed" = [5]\n', "topology.seed"),
    ('[scene.set]\n"preset" = ["paper"]\n', "preset"),
    ('cells = [16]\n[scene.set]\n"sim.dx" = [0.01]\n', "sim.dx"),
]


@pytest.mark.parametrize("extra, key", SHADOWED, ids=[k for _, k in SHADOWED])
def test_a_config_key_set_twice_by_one_scene_table_is_refused(tmp_path, extra, key):
    """Rule: a [scene.set] key that [scene.material] or a table key (dt, cfl, cells, frames, variant, seed, preset)
    also sets would be overwritten (or overwrite it), so one axis did nothing and its cells merged silently;
    ConfigError naming the key."""
    from fracture_gs.sweep import load_spec

    with pytest.raises(ConfigError) as info:
        load_spec(spec_file(tmp_path, SCENE.replace("particles = 300\n", "particles = 300\n" + extra)))
    msg = one_line(info.value)
    assert f"scene[0].set.{key}" in msg and "would do nothing" in msg


def test_set_keys_no_table_key_owns_still_expand(tmp_path):
    """Rule (no false refusal): [scene.set] keys of their own ("sim.contact.friction", a material_map entry) and a
    dt beside a set key of another name still make their cells."""
    from fracture_gs.sweep import expand, load_spec

    text = SCENE + 'dt = [1e-4]\n[scene.set]\n"sim.contact.friction" = [0.0, 0.3]\n"material_map.0.E" = [4e3]\n'
    assert len(expand(load_spec(spec_file(tmp_path, text)))) == 2


def test_a_splat_file_given_as_a_spec_says_so(small_ply):
    """Rule: `sweep scene.ply` names the file a splat file and where it belongs (it said "cannot be read as UTF-8
    text")."""
    from fracture_gs.sweep import load_spec

    with pytest.raises(ConfigError) as info:
        load_spec(small_ply)
    assert "splat file" in one_line(info.value) and "[[scene]]" in str(info.value)


# ---------------------------------------------------------------- sweep cache files


@pytest.fixture
def cached_cell(tmp_path):
    from fracture_gs.sweep import cache, expand, load_spec

    cell = expand(load_spec(spec_file(tmp_path, '[[accuracy]]\ncase = "bar"\ncells = [16]\ncfl = 0.4\n')))[0]
    row = {"status": "ok", "dt": 1e-3, "particles": 100, "substeps": 10, "wall_s": 1.0, "error": 0.01}
    cache.store(tmp_path, cell, {**row, "unit": "rel", "device": "cpu", "cell_s": 1.5})
    return cell, cache.cache_path(tmp_path, cell.id), cache


def test_a_cache_file_that_is_a_pipe_is_refused_without_reading(tmp_path, cached_cell):
    """Rule: a cache file that is not a regular file (a FIFO: reading it blocked for ever; /dev/zero: it never
    ended and filled the memory) is an OutputError naming it before it is opened. A writer thread feeds the pipe
    if someone opens it, so the code before the fix ended (with "not JSON") instead of hanging."""
    cell, path, cache = cached_cell
    path.unlink()
    os.mkfifo(path)

    done = threading.Event()

    def feed():
        end = time.monotonic() + 3.0
        while time.monotonic() < end and not done.is_set():
            try:
                fd = os.open(path, os.O_WRONLY | os.O_NONBLOCK)
            except OSError:  # no reader yet
                time.sleep(0.01)
                continue
            os.write(fd, b"not json")
            os.close(fd)
            return

    writer = threading.Thread(target=feed, daemon=True)
    writer.start()
    try:
        with pytest.raises(OutputError) as info:
            cache.load(tmp_path, cell)
    finally:
        done.set()
        writer.join()
    assert "not a regular file" in one_line(info.value)


def test_a_huge_cache_file_is_refused_by_its_size(tmp_path, cached_cell):
    """Rule: a cache file over 64 MiB is not one the driver wrote: refused by its size, unread (before, all of it
    was read into memory and parsed)."""
    cell, path, cache = cached_cell
    with open(path, "r+b") as f:
        f.truncate(65 * 2**20)  # sparse: costs no disk
    with pytest.raises(OutputError) as info:
        cache.load(tmp_path, cell)
    assert "MiB" in one_line(info.value)


def test_a_cache_file_with_a_bom_is_read(tmp_path, cached_cell):
    """Rule: a UTF-8 byte-order mark (an editor's) is not an error, as for configs and cameras.json (it was "not
    JSON")."""
    cell, path, cache = cached_cell
    path.write_bytes(b"\xef\xbb\xbf" + path.read_bytes())
    assert cache.load(tmp_path, cell)["particles"] == 100
