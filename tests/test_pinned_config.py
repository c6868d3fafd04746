"""Pinned rules of the config package (`fracture_gs.io.config`): round trips, file lookup, type errors and
the bounds of every range check, each at its edge, so that an off-by-one or a flipped comparison fails here.

Written against the public functions (`config_from_dict`, `load_config`, `dump_config`, `find_config`,
`apply_overrides`, ...), never line numbers. Unit-level: no simulation runs.
"""

from __future__ import annotations

import copy
import math

import pytest
import tomllib

from fracture_gs.config import SceneConfig
from fracture_gs.errors import ConfigError
from fracture_gs.io.config import (
    CONFIG_DIR,
    apply_overrides,
    builtin_configs,
    config_from_dict,
    config_to_dict,
    dump_config,
    find_config,
    load_config,
    parse_resolution,
    parse_variants,
)
from fracture_gs.io.config.build import describe
from fracture_gs.io.config.dump import toml_value

BASE = {"variants": ["baseline"]}  # the smallest valid dict: defaults everywhere, no provider needed


def _with(**dotted) -> dict:
    """BASE with `a__b__c=value` set as d["a"]["b"]["c"] (double underscores separate tables)."""
    d = copy.deepcopy(BASE)
    if any(k.startswith("capture__") for k in dotted):
        d["scene"] = "scene.ply"  # [capture] keys act on a captured scene only (a built-in one refuses them)
    for key, value in dotted.items():
        node = d
        parts = key.split("__")
        for p in parts[:-1]:
            node = node.setdefault(p, {})
        node[parts[-1]] = value
    return d


def _error(d: dict) -> ConfigError:
    with pytest.raises(ConfigError) as info:
        config_from_dict(d, source="t.toml")
    return info.value


def _reload(cfg: SceneConfig, tmp_path) -> SceneConfig:
    path = tmp_path / "again.toml"
    path.write_text(dump_config(cfg))
    return load_config(path)


# ---------------------------------------------------------------------------------------------
# dump → load


def test_every_builtin_config_dumps_and_loads_back_equal(tmp_path):
    """A config written by dump_config loads back equal (arrays, arrays of tables, nested tables, strings),
    for every built-in config."""
    names = builtin_configs()
    assert len(names) >= 5
    for name in names:
        cfg = load_config(name)
        assert _reload(cfg, tmp_path) == cfg, name


def test_a_config_with_every_table_kind_round_trips(tmp_path):
    """Every boundary type, material-map entries, oracle planes, capture regions and a scene path with quotes
    and non-ASCII letters survive dump → load unchanged (the boundary `type` key is written and read back)."""
    d = _with(
        name="cube A",
        sim__boundaries=[
            {"type": "plane", "point": [0, 0, 0.1], "normal": [0, 0, 1], "mode": "sticky", "friction": 0.2},
            {"type": "cuboid", "lower": [0.1, 0.1, 0.1], "upper": [0.2, 0.2, 0.2], "start": 0.0, "end": 0.5},
            {"type": "sphere", "center": [0.5, 0.5, 0.5], "radius": 0.05, "velocity": [1, 0, 0]},
            {"type": "region", "kind": "velocity", "lower": [0, 0, 0], "upper": [1, 1, 0.1]},
        ],
        material_map=[{"label": 0, "E": 3.0e3}, {"label": 2, "nu": 0.2}],
        topology__planes=[{"point": [0.5, 0.5, 0.5], "normal": [0, 1, 0], "latch_frame": 3}],
        capture__regions=[{"lower": [0, 0, 0], "upper": [1, 1, 1], "material": "plant"}],
        scene='dir/th "q" é.ply',
    )
    d["variants"] = ["baseline", "full"]
    d["topology"]["provider"] = "stress"
    cfg = config_from_dict(d)
    again = _reload(cfg, tmp_path)
    assert again == cfg
    assert [type(b).__name__ for b in again.sim.boundaries] == [
        "PlaneBoundary",
        "CuboidBoundary",
        "SphereBoundary",
        "ParticleRegion",
    ]
    assert again.scene == 'dir/th "q" é.ply'


@pytest.mark.parametrize(
    "value",
    [
        0.1,
        -2.5,
        1e-300,
        float("inf"),
        float("-inf"),
        -0.5,
        7,
        -3,
        True,
        False,
        "",
        'a "quoted" \\ back\nslash é',
        [1.0, 2, "x"],
        (0.5, [True, -1]),
        [],
    ],
)
def test_toml_value_reads_back_as_the_same_value(value):
    """Each scalar or inline array written by toml_value parses (tomllib) to the same value: infinities of
    either sign, floats at full precision, integers as integers, booleans, escaped strings, nested arrays."""
    parsed = tomllib.loads(f"x = {toml_value(value)}")["x"]

    def plain(v):
        return [plain(i) for i in v] if isinstance(v, (list, tuple)) else v

    assert parsed == plain(value)
    assert type(parsed) is type(plain(value))


def test_toml_value_writes_nan_and_refuses_other_objects():
    """NaN is written as TOML's nan; a value TOML cannot hold (a dict, None) raises TypeError naming its type."""
    assert math.isnan(tomllib.loads(f"x = {toml_value(float('nan'))}")["x"])
    with pytest.raises(TypeError, match="NoneType"):
        toml_value(None)


def test_capture_table_is_written_only_when_it_says_something():
    """config_to_dict leaves [capture] out for a built-in scene with default capture keys, and keeps it for a
    splat-file scene (where its defaults drive the capture)."""
    assert "capture" not in config_to_dict(config_from_dict(BASE))
    assert "capture" in config_to_dict(config_from_dict(_with(scene="thing.ply")))


# ---------------------------------------------------------------------------------------------
# finding files and extends


def test_builtin_configs_come_from_the_package_configs_folder():
    """The built-in configs are the TOML files of the package's own configs/ folder (bread, capture, ...), and
    a bare name finds its file there."""
    assert CONFIG_DIR.name == "configs" and CONFIG_DIR.parent.name == "fracture_gs"
    names = builtin_configs()
    assert {"bread", "capture", "recontact"} <= set(names)
    assert find_config("bread") == CONFIG_DIR / "bread.toml"
    assert find_config("bread.toml") == CONFIG_DIR / "bread.toml"


def test_unknown_bare_name_is_an_error_listing_the_builtins():
    """A bare name with no built-in file behind it is a ConfigError that lists the built-in names, not a path."""
    with pytest.raises(ConfigError, match="bread"):
        find_config("no_such_config_name")


def test_a_path_without_its_toml_suffix_finds_the_file(tmp_path):
    """`dir/name` finds `dir/name.toml` when only that exists."""
    (tmp_path / "mine.toml").write_text('variants = ["baseline"]\n')
    assert find_config(tmp_path / "mine") == tmp_path / "mine.toml"
    assert load_config(tmp_path / "mine").variants == ["baseline"]


def test_file_encoding_and_folder_errors(tmp_path):
    """A UTF-8 byte-order mark is not part of the TOML; a file that is not UTF-8 names the bad byte; a folder
    given as the config says so; an empty name is refused."""
    (tmp_path / "bom.toml").write_bytes(b'\xef\xbb\xbfvariants = ["baseline"]\n')
    assert load_config(tmp_path / "bom.toml").variants == ["baseline"]
    (tmp_path / "latin.toml").write_bytes(b'name = "caf\xe9"\n')
    with pytest.raises(ConfigError, match="byte 0xe9 at offset 11"):
        load_config(tmp_path / "latin.toml")
    with pytest.raises(ConfigError, match="is a folder"):
        find_config(tmp_path)
    with pytest.raises(ConfigError, match="empty"):
        find_config("  ")


def test_a_trainer_ply_is_named_after_its_model_folder(tmp_path):
    """A bare splat file is the built-in capture config with that scene; the reference trainer's
    model/point_cloud/iteration_N/point_cloud.ply is named after `model`, another file after its stem."""
    from fracture_gs.io.config.files import ply_config

    ply = tmp_path / "my garden" / "point_cloud" / "iteration_7000" / "point_cloud.ply"
    cfg = ply_config(ply)
    assert cfg.name == "my_garden" and cfg.scene == str(ply.resolve())
    assert cfg.capture == load_config("capture").capture
    assert ply_config(tmp_path / "statue.compressed.ply").name == "statue"


def test_extends_deep_merges_tables_and_replaces_arrays(tmp_path):
    """A file that extends another keeps the base's keys it does not set (tables merge key by key) and
    replaces arrays whole; a file without `extends` stands alone."""
    (tmp_path / "base.toml").write_text(
        'variants = ["baseline", "full"]\n[topology]\nprovider = "stress"\n[sim]\ndx = 0.03125\ndt = 2e-4\n'
    )
    (tmp_path / "child.toml").write_text('extends = "base"\nvariants = ["baseline"]\n[sim]\ndt = 1e-4\n')
    cfg = load_config(tmp_path / "child.toml")
    assert cfg.sim.dx == 0.03125 and cfg.sim.dt == 1e-4 and cfg.variants == ["baseline"]
    alone = load_config(tmp_path / "base.toml")
    assert alone.sim.dt == 2e-4 and alone.variants == ["baseline", "full"]


def test_extends_cycle_is_one_sentence(tmp_path):
    """Two files that extend each other are a ConfigError naming `extends` and the cycle, not a recursion."""
    (tmp_path / "a.toml").write_text('extends = "b"\n')
    (tmp_path / "b.toml").write_text('extends = "a"\n')
    with pytest.raises(ConfigError, match="cycle") as info:
        load_config(tmp_path / "a.toml")
    assert info.value.field == "extends"


# ---------------------------------------------------------------------------------------------
# building: types, tables, normals


def test_unknown_keys_get_the_closest_name_or_the_valid_list():
    """An unknown key close to a valid one gets that one name as the fix; one far from every key gets the list
    of valid keys of its table."""
    err = _error(_with(sim__dxx=0.1))
    assert err.field == "sim.dxx" and "did you mean 'dx'?" in str(err)
    err = _error(_with(render__zzzzqq=1))
    assert "valid keys in [render] are width, height" in str(err)
    assert "did you mean 'frames'?" in str(_error(_with(framse=3)))


def test_a_section_given_as_a_scalar_is_a_table_error():
    """`sim = 3` is refused as '[sim] must be a table', naming the section."""
    err = _error(_with(sim=3))
    assert err.field == "sim" and "must be a table" in str(err)


@pytest.mark.parametrize(
    "value, text", [([0.5], "an array of 1 item"), ([0.5, 0.5], "an array of 2 items"), ([], "an array of 0 items")]
)
def test_wrong_length_array_message_counts_its_items(value, text):
    """A 3-vector given with the wrong number of items says how many it had, in correct English (1 item, 2 items)."""
    err = _error(_with(render__background=value))
    assert f"not {text};" in str(err)


def test_describe_names_what_a_wrong_value_is():
    """The message fragment for a wrong value names its kind: boolean, string, number, table, array (counted)."""
    assert describe(True) == "the boolean true"
    assert describe("x") == "the string 'x'"
    assert describe(2.5) == "the number 2.5"
    assert describe({}) == "a table"
    assert describe((1,)) == "an array of 1 item"
    assert describe([1, 2, 3]) == "an array of 3 items"


def test_building_twice_gives_the_same_types():
    """Type checking works the same on the first and the second build of each section (the hints cache)."""
    for _ in range(2):
        cfg = config_from_dict(_with(sim__dx=0.03125, material__E=500))
        assert cfg.sim.dx == 0.03125 and isinstance(cfg.material.E, float)
    assert "must be a number" in str(_error(_with(sim__dx="fast")))


def test_plane_normals_are_normalized_and_other_boundaries_keep_their_fields():
    """A plane boundary's normal is scaled to unit length on load; a cuboid next to it loads untouched."""
    cfg = config_from_dict(
        _with(
            sim__boundaries=[
                {"type": "cuboid", "lower": [0.1, 0.1, 0.1], "upper": [0.3, 0.3, 0.3]},
                {"type": "plane", "normal": [0.0, 0.0, 2.0]},
                {"type": "plane", "normal": [3.0, 4.0, 0.0]},
            ]
        )
    )
    assert cfg.sim.boundaries[0].lower == (0.1, 0.1, 0.1)
    assert cfg.sim.boundaries[1].normal == (0.0, 0.0, 1.0)
    assert cfg.sim.boundaries[2].normal == pytest.approx((0.6, 0.8, 0.0))


# ---------------------------------------------------------------------------------------------
# value checks at their edges


ACCEPT_REJECT = [
    # (dotted key, accepted value, rejected value): the accepted one sits at (or next to) the bound
    ("frame_dt", 1e-4, 0.0),
    ("frame_dt", 0.01, -0.01),
    ("material__E", 1e-6, 0.0),
    ("material__E", 2e6, -1.0),
    ("material__density", 1.0, 0.0),
    ("material__nu", 0.0, -0.01),
    ("material__nu", 0.499, 0.5),
    ("material__friction_angle", 0.0, 90.0),
    ("material__hardening", 0.0, -0.1),
    ("material__sigma_R", 1.0, 0.0),
    ("material__yield_stress", 1.0, -1.0),
    ("frames", 1, 0),
    ("sim__cfl", 1.0, 1.01),
    ("sim__cfl", 0.01, 0.0),
    ("sim__restitution", 1.0, 1.01),
    ("sim__restitution", 0.0, -0.01),
    ("sim__wall_cells", 0, -1),
    ("sim__grid_margin", 0.0, -0.1),
    ("sim__eps_mass", 0.0, -1e-9),
    ("sim__field_slots", 2, 1),
    ("sim__field_slots", 8, 9),
    ("sim__max_fragments", 2, 1),
    ("sim__max_fragments", 4096, 4097),
    ("sim__max_grid_cells", 64**3, 124),
    ("sim__dx", 0.01, 0.0),
    ("sim__contact__friction", 0.0, -0.1),
    ("sim__contact__fill", 0.1, 0.0),
    ("topology__latch_frame", 0, -1),
    ("topology__min_particles", 1, 0),
    ("topology__persist_frames", 1, 0),
    ("topology__band_width", 0.5, 0.0),
    ("topology__pair_radius", 0.5, 0.0),
    ("topology__direction_agreement", 1.0, 1.01),
    ("topology__direction_agreement", 0.0, -0.01),
    ("topology__max_events", 1, 0),
    ("topology__cells", 1, 0),
    ("topology__impact_radius", 0.01, 0.0),
    ("topology__normal", [0.0, 0.0, 1.0], [0.0, 0.0, 0.0]),
    ("render__width", 2, 1),
    ("render__width", 8192, 8193),
    ("render__height", 2, 1),
    ("render__fps", 1, 0),
    ("render__inset_radius", 0, -1),
    ("render__inset_zoom", 0.5, 0.0),
    ("render__background", [0.0, 1.0, 0.5], [0.0, 1.01, 0.5]),
    ("render__max_stretch", 1.01, 1.0),
    ("render__camera__fov_deg", 179.0, 179.5),
    ("render__camera__fov_deg", 1.0, 0.0),
    ("capture__cells_across", 4, 3),
    ("capture__cells_across", 1024, 1025),
    ("capture__max_particles", 1, 0),
]


@pytest.mark.parametrize("key, good, bad", ACCEPT_REJECT, ids=[f"{k}={b}" for k, _, b in ACCEPT_REJECT])
def test_each_range_check_accepts_its_bound_and_rejects_past_it(key, good, bad):
    """Each value check accepts the value at its documented bound (positive, at least, within, open-high) and
    rejects the first value past it with a ConfigError naming that field."""
    cfg = config_from_dict(_with(**{key: good}))
    assert cfg is not None
    err = _error(_with(**{key: bad}))
    assert err.field.split("[")[0] == key.replace("__", "."), str(err)


def test_material_map_entries_get_the_same_checks_as_the_material():
    """A material-map entry is checked like [material] (E > 0, ν < 0.5) under its own name; labels are >= 0
    and unique."""
    assert config_from_dict(_with(material_map=[{"label": 0, "E": 1.0, "nu": 0.0}])).material_map[0].E == 1.0
    assert _error(_with(material_map=[{"label": 0, "E": 0.0}])).field == "material_map[0].E"
    assert _error(_with(material_map=[{"label": 0, "nu": 0.5}])).field == "material_map[0].nu"
    assert _error(_with(material_map=[{"label": -1}])).field == "material_map[0].label"
    assert _error(_with(material_map=[{"label": 1}, {"label": 1}])).field == "material_map[1].label"


def test_positive_checks_refuse_zero_negative_and_keep_positive_values():
    """A `positive` field keeps a positive value as given and refuses zero and negatives, naming the field."""
    assert config_from_dict(_with(frame_dt=0.02, sim__dt=1e-4)).frame_dt == 0.02
    for bad in (0.0, -1e-3, -5.0):
        assert _error(_with(frame_dt=bad)).field == "frame_dt"
        assert "positive" in str(_error(_with(topology__band_width=bad)))


@pytest.mark.parametrize("wall, least", [(0, 5), (1, 5), (3, 8), (6, 14)])
def test_grid_shape_minimum_is_the_one_the_message_names(wall, least):
    """A grid shape below max(5, 2·wall_cells + 2) nodes per axis is refused with a fix that names exactly that
    minimum, and the named minimum is accepted."""
    err = _error(_with(sim__wall_cells=wall, sim__grid_shape=[least - 1, least, least]))
    assert err.field == "sim.grid_shape[0]"
    assert f"use at least {least} nodes per axis" in str(err)
    cfg = config_from_dict(_with(sim__wall_cells=wall, sim__grid_shape=[least, least, least]))
    assert cfg.sim.grid_shape == (least, least, least)


def test_explicit_grid_over_the_node_cap_is_refused():
    """An explicit grid of more nodes than sim.max_grid_cells is refused; exactly at the cap it is accepted."""
    assert config_from_dict(_with(sim__grid_shape=[10, 10, 10], sim__max_grid_cells=1000)).sim.grid_shape == (10,) * 3
    assert _error(_with(sim__grid_shape=[10, 10, 11], sim__max_grid_cells=1000)).field == "sim.grid_shape"


def test_substep_must_fit_in_a_frame_and_the_substep_cap():
    """sim.dt equal to frame_dt is accepted, longer is refused; frame_dt / dt above max_substeps_per_frame is
    refused, at it accepted."""
    assert config_from_dict(_with(frame_dt=0.01, sim__dt=0.01)).sim.dt == 0.01
    assert _error(_with(frame_dt=0.01, sim__dt=0.011)).field == "sim.dt"
    ok = _with(frame_dt=0.01, sim__dt=1e-3, sim__max_substeps_per_frame=10)
    assert config_from_dict(ok).sim.max_substeps_per_frame == 10
    bad = _with(frame_dt=0.01, sim__dt=1e-3, sim__max_substeps_per_frame=9)
    assert _error(bad).field == "sim.max_substeps_per_frame"


def test_latch_frame_may_be_any_frame_of_the_run():
    """topology.latch_frame 0 (latch at once) and = frames (the last) are accepted; past the last is refused."""
    assert config_from_dict(_with(topology__latch_frame=0)).topology.latch_frame == 0
    assert config_from_dict(_with(frames=12, topology__latch_frame=12)).topology.latch_frame == 12
    assert _error(_with(frames=12, topology__latch_frame=13)).field == "topology.latch_frame"
    plane = {"point": [0.5, 0.5, 0.5], "normal": [1, 0, 0], "latch_frame": 0}
    assert config_from_dict(_with(topology__planes=[plane])).topology.planes[0].latch_frame == 0
    assert _error(_with(topology__planes=[{**plane, "latch_frame": -1}])).field == "topology.planes[0].latch_frame"


@pytest.mark.parametrize("kind", ["cuboid", "sphere", "region"])
def test_boundary_time_windows(kind):
    """A boundary's [start, end] may be a single instant (start = end) or start at 0; end before start or a
    negative start is refused, naming the boundary's start."""
    extra = {"radius": 0.05} if kind == "sphere" else {"lower": [0.1, 0.1, 0.1], "upper": [0.2, 0.2, 0.2]}
    for start, end in ((0.0, 0.0), (0.2, 0.2), (0.0, 1.0)):
        cfg = config_from_dict(_with(sim__boundaries=[{"type": kind, "start": start, "end": end, **extra}]))
        assert (cfg.sim.boundaries[0].start, cfg.sim.boundaries[0].end) == (start, end)
    for start, end in ((0.3, 0.2), (-0.1, 0.2)):
        err = _error(_with(sim__boundaries=[{"type": kind, "start": start, "end": end, **extra}]))
        assert err.field == "sim.boundaries[0].start"


@pytest.mark.parametrize("kind", ["cuboid", "region"])
def test_boxes_need_positive_thickness_on_every_axis(kind):
    """A box with lower = upper on one axis (zero thickness) is refused; any positive thickness is accepted."""
    box = {"type": kind, "lower": [0.1, 0.1, 0.1], "upper": [0.2, 0.2, 0.2]}
    assert config_from_dict(_with(sim__boundaries=[box])).sim.boundaries[0].upper == (0.2, 0.2, 0.2)
    flat = {**box, "upper": [0.2, 0.1, 0.2]}
    assert _error(_with(sim__boundaries=[flat])).field == "sim.boundaries[0].lower"


def test_sphere_radius_and_plane_friction():
    """A sphere boundary needs a positive radius; a plane's friction may be 0 but not negative, and its normal
    must be nonzero."""
    assert _error(_with(sim__boundaries=[{"type": "sphere", "radius": 0.0}])).field == "sim.boundaries[0].radius"
    assert config_from_dict(_with(sim__boundaries=[{"type": "plane", "friction": 0.0}])).sim.boundaries[0].friction == 0
    assert _error(_with(sim__boundaries=[{"type": "plane", "friction": -0.1}])).field == "sim.boundaries[0].friction"
    assert _error(_with(sim__boundaries=[{"type": "plane", "normal": [0, 0, 0]}])).field == "sim.boundaries[0].normal"


def test_camera_up_parallel_to_the_view_is_refused():
    """A camera whose up vector is parallel (either sense) to the viewing direction is refused; a tilted one is
    accepted; eye = target is refused."""
    cam = {"eye": [0.5, 0.5, 2.0], "target": [0.5, 0.5, 0.0]}
    assert _error(_with(render__camera={**cam, "up": [0, 0, 1]})).field == "render.camera.up"
    assert _error(_with(render__camera={**cam, "up": [0, 0, -3]})).field == "render.camera.up"
    assert config_from_dict(_with(render__camera={**cam, "up": [0, 0.01, 1]})).render.camera.up == (0, 0.01, 1)
    same = {"eye": [0.5, 0.5, 0.5], "target": [0.5, 0.5, 0.5], "up": [0, 0, 1]}
    assert _error(_with(render__camera=same)).field == "render.camera.target"


def test_non_finite_numbers_are_refused_anywhere():
    """NaN or inf in any float, scalar or vector component, nested in tables or arrays of tables, is refused
    naming that field."""
    assert _error(_with(sim__gravity=[0, 0, float("nan")])).field == "sim.gravity"
    assert _error(_with(material__E=float("inf"))).field == "material.E"
    assert _error(_with(material_map=[{"label": 0, "E": float("-inf")}])).field == "material_map[0].E"


def test_capture_regions_need_a_box_and_a_preset():
    """A material region needs lower < upper on every axis and a real preset (not "config")."""
    region = {"lower": [0, 0, 0], "upper": [1, 1, 1], "material": "wood"}
    assert config_from_dict(_with(capture__regions=[region])).capture.regions[0].material == "wood"
    assert _error(_with(capture__regions=[{**region, "upper": [1, 0, 1]}])).field == "capture.regions[0]"
    assert _error(_with(capture__regions=[{**region, "material": "config"}])).field == "capture.regions[0].material"


def test_variants_need_a_provider_unless_only_baseline():
    """Any variant but baseline needs topology.provider other than "none"; baseline alone runs without one."""
    assert config_from_dict(BASE).topology.provider == "none"
    err = _error(_with(variants=["baseline", "full"]))
    assert err.field == "topology.provider"
    assert config_from_dict(_with(variants=["full"], topology__provider="oracle")).variants == ["full"]
    assert _error(_with(variants=["full", "full"], topology__provider="stress")).field == "variants"
    assert _error(_with(variants=[])).field == "variants"


# ---------------------------------------------------------------------------------------------
# command-line overrides


def test_resolution_bounds():
    """--resolution accepts 2x2 and 8192x8192, refuses 1 pixel or 8193 on a side, and reads '640×480'."""
    assert parse_resolution("2x2") == (2, 2)
    assert parse_resolution("8192x8192") == (8192, 8192)
    assert parse_resolution("640×480") == (640, 480)
    assert parse_resolution((30, 20)) == (30, 20)
    for bad in ("1x2", "2x1", "8193x10", "10x8193", "64", "-64x48", "axb"):
        with pytest.raises(ConfigError) as info:
            parse_resolution(bad)
        assert info.value.field == "--resolution"


def test_variants_flag_suggests_the_closest_name():
    """An unknown variant name gets the one closest name as the fix; repeats and empty lists are refused."""
    assert parse_variants("baseline, full") == ["baseline", "full"]
    with pytest.raises(ConfigError, match="did you mean 'full'"):
        parse_variants("baseline,fulll")
    for bad in ("baseline,baseline", ",", ""):
        with pytest.raises(ConfigError):
            parse_variants(bad)


def test_preset_override_rescales_an_explicit_grid_and_dt():
    """--preset paper on a small config halves Δx, doubles the explicit grid's nodes (same box) and halves
    sim.dt (same CFL number); applying it again changes nothing; the input config is not modified."""
    small = config_from_dict(_with(sim__grid_shape=[64, 32, 16], sim__dt=2e-4, sim__dx=1 / 64))
    paper = apply_overrides(small, preset="paper")
    assert paper.sim.dx == pytest.approx(1 / 128)
    assert paper.sim.grid_shape == (128, 64, 32)
    assert paper.sim.dt == pytest.approx(1e-4)
    assert paper.preset == "paper"
    assert apply_overrides(paper, preset="paper") == paper
    assert small.sim.dx == 1 / 64 and small.sim.grid_shape == (64, 32, 16)
    back = apply_overrides(paper, preset="small")
    assert back.sim.grid_shape == (64, 32, 16) and back.sim.dt == pytest.approx(2e-4)


def test_frames_override_must_be_a_positive_integer():
    """--frames 1 is accepted; 0, -3, 2.5 and True are refused naming --frames."""
    cfg = config_from_dict(BASE)
    assert apply_overrides(cfg, frames=1).frames == 1
    for bad in (0, -3, 2.5, True):
        with pytest.raises(ConfigError) as info:
            apply_overrides(cfg, frames=bad)
        assert info.value.field == "--frames"


def test_capture_rotation_determinant_uses_every_cofactor():
    """capture.rotation must be a proper rotation (determinant +1), whatever its rows look like: the cyclic axis
    permutation x→y→z loads, and the same matrix with one row negated (determinant −1, a reflection whose third
    column carries the sign) is refused naming capture.rotation."""
    cyclic = [[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]
    cfg = config_from_dict(_with(scene="thing.ply", capture__rotation=cyclic))
    assert [list(r) for r in cfg.capture.rotation] == cyclic
    mirrored = [[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, -1.0, 0.0]]
    err = _error(_with(scene="thing.ply", capture__rotation=mirrored))
    assert err.field == "capture.rotation" and "reflection" in str(err)
