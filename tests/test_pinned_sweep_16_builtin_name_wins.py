"""Pinned rule of a scene cell's `cells` axis (`fracture_gs.sweep.expansion._apply_cells`, `scene_config`): a
built-in scene name is the built-in scene even when a splat file of the same name sits in the working folder
(config validation reads it the same way, built-in first), so `cells` rescales the built-in's explicit grid and
never turns into the captured scenes' `capture.cells_across`; only a scene that is not built-in and is a splat
file takes that route.

Unit-level: configs are resolved and validated, nothing is simulated.
"""

from __future__ import annotations

from fracture_gs import assets
from fracture_gs.io.detect import is_splat_file
from fracture_gs.io.ply import save_ply
from fracture_gs.sweep import expansion as E
from fracture_gs.sweep.spec import load_spec

SPEC = '[[scene]]\nconfig = "bread"\nvariant = "baseline"\ncells = [20]\n'


def _splat_named(folder, name: str) -> None:
    """A real (tiny) PLY splat file called `name`, without a suffix: only its content says it is a splat file."""
    save_ply(assets.build("bread", size="small", n=32, seed=0), folder / name)
    assert is_splat_file(name)  # the file is there and reads as a splat file


def test_a_builtin_name_with_a_same_named_splat_file_keeps_its_grid(tmp_path, monkeypatch):
    """With a splat file called `bread` in the working folder, cells = 20 on the built-in `bread` scene still gives
    Δx = box side / 20 with each axis rescaled (at least 4 cells) and a fixed Δt scaled by the same ratio, and adds
    no capture table; a suffix-less splat path that is not a built-in name gets capture.cells_across instead."""
    monkeypatch.chdir(tmp_path)
    _splat_named(tmp_path, "bread")
    d = {"scene": "bread", "sim": {"grid": "explicit", "dx": 0.1, "grid_shape": [10, 5, 2], "dt": 1e-3}}
    E._apply_cells(d, 20, "scene[0]", "s.toml")
    assert d == {"scene": "bread", "sim": {"grid": "explicit", "dx": 0.05, "grid_shape": [20, 10, 4], "dt": 5e-4}}
    _splat_named(tmp_path, "scan")
    d = {"scene": "scan", "sim": {"grid": "explicit", "dx": 0.1, "grid_shape": [10, 5, 2], "dt": 1e-3}}
    E._apply_cells(d, 20, "scene[0]", "s.toml")
    assert d == {
        "scene": "scan",
        "sim": {"grid": "explicit", "dx": 0.1, "grid_shape": [10, 5, 2], "dt": 1e-3},
        "capture": {"cells_across": 20},
    }


def test_a_builtin_cell_beside_a_same_named_splat_file_is_a_valid_builtin_config(tmp_path, monkeypatch):
    """The whole cell: the built-in `bread` config with cells = 20, made while a splat file `bread` sits in the
    working folder, is a valid config of the built-in scene whose Δx is its box's largest side / 20 and whose
    capture table holds only defaults (a built-in scene refuses capture keys)."""
    spec_dir = tmp_path / "specs"
    spec_dir.mkdir()
    (spec_dir / "s.toml").write_text(SPEC)
    spec = load_spec(spec_dir / "s.toml")
    base = E._base_config(spec, "scene[0]", "bread", {})
    side = max(base.sim.grid_shape) * base.sim.dx
    monkeypatch.chdir(tmp_path)
    _splat_named(tmp_path, "bread")
    cfg = E.scene_config(spec, "scene[0]", "bread", base, spec.scenes[0], 20, None, {}, 0, "baseline")
    assert cfg.scene == "bread"
    assert abs(cfg.sim.dx - side / 20) < 1e-12 * side
    assert cfg.capture == type(cfg.capture)()
