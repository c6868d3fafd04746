"""TOML configs: built-ins load, round-trip, strict keys/types/values, extends, overrides."""

from __future__ import annotations

import copy
from pathlib import Path

import pytest
import tomllib

from fracture_gs.config import CuboidBoundary, ParticleRegion, PlaneBoundary, SceneConfig
from fracture_gs.io.config import (
    CONFIG_DIR,
    ConfigError,
    apply_overrides,
    builtin_configs,
    config_from_dict,
    config_to_dict,
    dump_config,
    find_config,
    load_config,
    parse_resolution,
    parse_variants,
    validate,
)

REPO = Path(__file__).resolve().parent.parent
SCENES = ("bread", "ficus", "recontact", "beam", "plane_drop", "plate_drop")


def write(tmp_path: Path, text: str, name: str = "x.toml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def error_of(tmp_path: Path, text: str) -> ConfigError:
    """Load `text` as a config file (in tmp_path) and return the ConfigError it raises."""
    path = write(tmp_path, text)
    with pytest.raises(ConfigError) as info:
        load_config(path)
    return info.value


# ---------------------------------------------------------------- built-ins


def test_builtin_list_has_scenes_and_experiments():
    names = builtin_configs()
    for scene in SCENES:
        assert scene in names
    assert any(n.startswith("exp_table3") for n in names)
    assert any(n.startswith("exp_table5") for n in names)


def test_repo_configs_dir_is_the_package_data():
    assert (REPO / "configs").resolve() == CONFIG_DIR
    assert (REPO / "configs" / "bread.toml").is_file()


@pytest.mark.parametrize("name", builtin_configs())
def test_builtin_loads_validates_and_round_trips(name):
    cfg = load_config(name)
    assert isinstance(cfg, SceneConfig)
    validate(cfg)
    assert load_config(find_config(name)) == cfg
    text = dump_config(cfg)
    assert config_from_dict(tomllib.loads(text)) == cfg
    assert config_from_dict(config_to_dict(cfg)) == cfg


def test_round_trip_through_a_file(tmp_path):
    cfg = load_config("bread")
    path = write(tmp_path, dump_config(cfg, header="generated\nby a test"))
    assert load_config(path) == cfg
    assert path.read_text().startswith("# generated\n# by a test\n")


def test_scene_geometry_contracts():
    bread = load_config("bread")
    assert (bread.frames, bread.frame_dt, bread.material.E, bread.material.density, bread.material.sigma_R) == (
        90,
        0.01,
        2e3,
        200,
        50,
    )
    assert bread.topology.provider == "stress" and bread.variants == ["baseline", "stress_zero", "full"]
    assert {e.label for e in bread.material_map} == {0, 1}
    grips = [b for b in bread.sim.boundaries if isinstance(b, CuboidBoundary)]
    assert sorted(g.velocity[0] > 0 for g in grips) == [False, True]
    ficus = load_config("ficus")
    assert (ficus.frames, ficus.frame_dt, ficus.material.E, ficus.material.sigma_R) == (44, 0.04, 2e6, 5e4)
    rc = load_config("recontact")
    assert rc.sim.gravity == (0.0, 0.0, 0.0) and rc.topology.provider == "oracle"
    regions = [b for b in rc.sim.boundaries if isinstance(b, ParticleRegion)]
    # zero total momentum with the 2:1 mass ratio, relative normal speed 0.6
    momentum = [2 * a + b for a, b in zip(regions[0].velocity, regions[1].velocity)]
    assert momentum == pytest.approx([0, 0, 0]) and regions[0].velocity[0] - regions[1].velocity[0] == pytest.approx(
        0.6
    )
    drop = load_config("plane_drop")
    plane = next(b for b in drop.sim.boundaries if isinstance(b, PlaneBoundary))
    assert plane.mode == "slip" and plane.point[2] == pytest.approx(0.1)


def test_experiment_configs():
    assert load_config("exp_table3_bread").variants == ["baseline", "probe_latch", "stress_zero", "full"]
    vlm, manual = load_config("exp_table5_bread_vlm"), load_config("exp_table5_bread_manual")
    assert (vlm.material.E, vlm.material.sigma_R) == (2.5e3, 55.0)
    assert (manual.material.E, manual.material.sigma_R) == (2e3, 50.0)
    assert load_config("exp_table5_ficus_vlm").material.sigma_R == 5.5e4


# ---------------------------------------------------------------- strictness


def test_unknown_key_suggests_closest(tmp_path):
    err = error_of(tmp_path, "[sim]\ngravty = [0, 0, -9.8]\n")
    assert str(err) == f"{err.source}: unknown key 'sim.gravty'; did you mean 'gravity'?"
    assert err.source.endswith("x.toml") and err.field == "sim.gravty"


def test_unknown_key_without_close_match_lists_keys(tmp_path):
    err = error_of(tmp_path, "zzz = 1\n")
    assert "unknown key 'zzz'" in str(err) and "frame_dt" in str(err)


def test_unknown_key_in_boundary_and_material_map(tmp_path):
    err = error_of(tmp_path, '[[sim.boundaries]]\ntype = "plane"\nnormel = [0, 0, 1]\n')
    assert err.field == "sim.boundaries[0].normel" and "'normal'" in str(err)
    err = error_of(tmp_path, "[[material_map]]\nlabel = 0\nsigmaR = 3.0\n")
    assert err.field == "material_map[0].sigmaR" and "'sigma_R'" in str(err)


PROVIDER = '[topology]\nprovider = "stress"\n'

BAD = [
    ('[sim]\ndt = "1e-4"\n', "sim.dt", "without quotes"),
    ("[sim]\ngravity = [0, 1]\n", "sim.gravity", "3 numbers"),
    ("[sim]\ngrid_shape = [64, 64.5, 64]\n", "sim.grid_shape[1]", "integer"),
    ("[sim]\nadaptive_dt = 1\n", "sim.adaptive_dt", "true or false"),
    ("sim = 3\n", "sim", "table"),
    ('frames = "ten"\n', "frames", "integer"),
    ('[sim]\nvariant = "ful"\n', "sim.variant", "did you mean 'full'"),
    ('variants = ["baseline", "ful"]\n' + PROVIDER, "variants[1]", "did you mean 'full'"),
    ('[material]\nmodel = "rubber"\n', "material.model", "fixed_corotated"),
    ('[[material_map]]\nlabel = 1\nmodel = "sand"\n', "material_map[0].model", "drucker_prager"),
    ('[[sim.boundaries]]\ntype = "plane"\nmode = "stiky"\n', "sim.boundaries[0].mode", "did you mean 'sticky'"),
    ('[[sim.boundaries]]\ntype = "plan"\n', "sim.boundaries[0].type", "did you mean type = 'plane'"),
    ("[[sim.boundaries]]\nlower = [0, 0, 0]\n", "sim.boundaries[0].type", "no type"),
    # a type that is not a string (a list, a table) cannot be looked up: the same sentence, not a TypeError
    ("[[sim.boundaries]]\ntype = [0.2, 0.35]\n", "sim.boundaries[0].type", "has type = [0.2, 0.35]; set type to"),
    ("[[sim.boundaries]]\ntype = {a = 1}\n", "sim.boundaries[0].type", "set type to one of 'plane'"),
    (
        '[[sim.boundaries]]\ntype = "cuboid"\nlower = [1, 0, 0]\nupper = [0, 1, 1]\n',
        "sim.boundaries[0].lower",
        "lower < upper",
    ),
    ('[[sim.boundaries]]\ntype = "plane"\nnormal = [0, 0, 0]\n', "sim.boundaries[0].normal", "nonzero"),
    ("[material]\nnu = 0.5\n", "material.nu", "below 0.5"),
    ("[material]\nnu = -0.1\n", "material.nu", "[0.0, 0.5)"),
    ("[material]\nE = 0\n", "material.E", "positive"),
    ("[material]\ndensity = -200.0\n", "material.density", "positive"),
    ("[[material_map]]\nlabel = 0\nE = -1.0\n", "material_map[0].E", "positive"),
    ("[sim]\ndt = 0.0\n", "sim.dt", "positive"),
    ("[sim]\ndx = -0.01\n", "sim.dx", "positive"),
    ("frames = 0\n", "frames", "outside [1, 1000000]"),
    ("[render]\nwidth = 1\n", "render.width", "outside [2, 8192]"),
    ("[render]\nheight = 0\n", "render.height", "outside [2, 8192]"),
    ('[topology]\nprovider = "orcale"\n', "topology.provider", "did you mean 'oracle'"),
    ('preset = "huge"\n', "preset", "small, paper"),
    ('variants = ["full"]\n', "topology.provider", "need a fracture event provider"),
    ('extends = "no_such_config"\n', "extends", "names no config file"),
]


@pytest.mark.parametrize("text,field,fix", BAD, ids=[b[1] + ":" + b[2] for b in BAD])
def test_invalid_values_name_file_field_and_fix(tmp_path, text, field, fix):
    err = error_of(tmp_path, text)
    message = str(err)
    assert isinstance(err, ValueError)
    assert err.field == field, message
    assert message.startswith(err.source + ": ") and err.source.endswith("x.toml")
    assert field.split("[")[0].split(".")[-1] in message or field in message
    assert fix in message
    assert "\n" not in message


def test_invalid_toml_syntax(tmp_path):
    err = error_of(tmp_path, "x = [\n")
    assert "invalid TOML" in str(err) and err.source.endswith("x.toml")


def test_missing_file_lists_builtins(tmp_path):
    with pytest.raises(ConfigError) as info:
        load_config(tmp_path / "nope.toml")
    assert "nope.toml" in str(info.value) and "bread" in str(info.value) and "recontact" in str(info.value)


def test_find_config_resolves_names_and_paths(tmp_path):
    assert find_config("bread") == CONFIG_DIR / "bread.toml"
    assert find_config("bread.toml") == CONFIG_DIR / "bread.toml"
    path = write(tmp_path, "frames = 3\n", "mine.toml")
    assert find_config(path) == path
    assert find_config(tmp_path / "mine") == path


def test_normals_normalized_and_arrays_become_tuples():
    cfg = config_from_dict(
        {
            "sim": {
                "boundaries": [{"type": "plane", "normal": [0, 0, 2], "point": [0, 0, 1]}],
                "grid_shape": [8, 8, 8],
            },
            "topology": {"provider": "oracle", "normal": [3, 4, 0]},
        }
    )
    assert cfg.sim.boundaries[0].normal == (0.0, 0.0, 1.0)
    assert cfg.topology.normal == pytest.approx((0.6, 0.8, 0.0))
    assert isinstance(cfg.sim.grid_shape, tuple) and cfg.sim.boundaries[0].point == (0.0, 0.0, 1.0)


def test_material_model_and_sim_material_follow_each_other():
    assert (
        config_from_dict({"material": {"model": "neo_hookean"}, "variants": ["baseline"]}).sim.material == "neo_hookean"
    )
    assert (
        config_from_dict({"sim": {"material": "neo_hookean"}, "variants": ["baseline"]}).material.model == "neo_hookean"
    )
    with pytest.raises(ConfigError, match="disagrees"):
        config_from_dict({"sim": {"material": "neo_hookean"}, "material": {"model": "fixed_corotated"}})


def test_config_from_dict_accepts_dataclass_boundaries():
    cfg = config_from_dict(
        {
            "sim": {"boundaries": [PlaneBoundary(mode="sticky"), CuboidBoundary(upper=(1, 1, 1))]},
            "variants": ["baseline"],
        }
    )
    assert cfg.sim.boundaries[0] == PlaneBoundary(mode="sticky")
    assert cfg.sim.boundaries[1].upper == (1.0, 1.0, 1.0)


# ---------------------------------------------------------------- extends


def test_extends_deep_merges_tables_and_replaces_arrays(tmp_path):
    path = write(
        tmp_path,
        'extends = "bread"\nname = "mine"\nvariants = ["full"]\n[material]\nE = 3000.0\n'
        "[render.camera]\nfov_deg = 30.0\n",
    )
    cfg, bread = load_config(path), load_config("bread")
    assert cfg.name == "mine" and cfg.variants == ["full"]
    assert cfg.material.E == 3000.0 and cfg.material.sigma_R == bread.material.sigma_R  # merged, not replaced
    assert cfg.render.camera.fov_deg == 30.0 and cfg.render.camera.eye == bread.render.camera.eye
    assert cfg.sim.boundaries == bread.sim.boundaries and cfg.material_map == bread.material_map


def test_extends_relative_path_chain_and_errors(tmp_path):
    write(tmp_path, 'extends = "bread"\nframes = 12\n', "base.toml")
    child = write(tmp_path, 'extends = "base.toml"\nname = "child"\n', "child.toml")
    cfg = load_config(child)
    assert (cfg.frames, cfg.name, cfg.scene) == (12, "child", "bread")
    # an error inside the base names the base file
    write(tmp_path, 'extends = "bread"\n[sim]\ngravty = [0, 0, 0]\n', "base.toml")
    with pytest.raises(ConfigError) as info:
        load_config(child)
    assert info.value.source.endswith("base.toml") and "did you mean 'gravity'" in str(info.value)
    # cycles
    write(tmp_path, 'extends = "b.toml"\n', "a.toml")
    write(tmp_path, 'extends = "a.toml"\n', "b.toml")
    with pytest.raises(ConfigError, match="cycle"):
        load_config(tmp_path / "a.toml")


# ---------------------------------------------------------------- overrides


def test_preset_paper_changes_grid_and_dt():
    small = load_config("bread")
    paper = apply_overrides(small, preset="paper")
    assert paper.preset == "paper" and paper.sim.grid_shape == (128, 128, 128)
    assert paper.sim.dx == 1 / 128 and paper.sim.dt == small.sim.dt / 2
    assert small.sim.grid_shape == (64, 64, 64)  # input untouched
    assert apply_overrides(paper, preset="paper") == paper  # idempotent
    assert apply_overrides(paper, preset="small") == small


def test_frames_resolution_variants_overrides():
    cfg = apply_overrides(load_config("bread"), frames=5, resolution="64x48", variants="baseline,full")
    assert (cfg.frames, cfg.render.width, cfg.render.height, cfg.variants) == (5, 64, 48, ["baseline", "full"])
    assert apply_overrides(cfg, resolution=(32, 16), variants=["stress_zero"]).render.width == 32


@pytest.mark.parametrize(
    "kwargs,flag",
    [
        ({"preset": "huge"}, "--preset"),
        ({"frames": 0}, "--frames"),
        ({"resolution": "640"}, "--resolution"),
        ({"resolution": "1x480"}, "--resolution"),
        ({"variants": "full,nope"}, "--variants"),
        ({"variants": "full,full"}, "--variants"),
    ],
)
def test_bad_overrides(kwargs, flag):
    with pytest.raises(ConfigError) as info:
        apply_overrides(load_config("bread"), **kwargs)
    assert info.value.field == flag and str(info.value).startswith(flag)


def test_parse_helpers():
    assert parse_resolution("640x480") == (640, 480)
    assert parse_variants(" baseline , full ") == ["baseline", "full"]


def test_validate_catches_programmatic_mistakes():
    cfg = copy.deepcopy(load_config("bread"))
    cfg.material.nu = 0.7
    with pytest.raises(ConfigError, match="material.nu"):
        validate(cfg, "mine")
    cfg = copy.deepcopy(load_config("bread"))
    cfg.sim.boundaries.append("floor")
    with pytest.raises(ConfigError, match=rf"sim.boundaries\[{len(cfg.sim.boundaries) - 1}\]"):
        validate(cfg)
