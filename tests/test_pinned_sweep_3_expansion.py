"""Pinned rules of a sweep spec's expansion (`fracture_gs.sweep.expansion`): a dotted `[scene.set]` key reaching
into arrays by index, a `dt` / `cfl` step switching the config between fixed and adaptive substeps, `cells`
rescaling the grid (and a fixed Δt with it), repeated cells merged into their first occurrence with every
label and counted by the progress callback, and a cell's short repr.

Unit-level calls only: specs are expanded (configs resolved and validated), nothing is simulated.
"""

from __future__ import annotations

import pytest

from fracture_gs.errors import ConfigError
from fracture_gs.sweep import expansion as E
from fracture_gs.sweep.spec import load_spec


def spec(tmp_path, text: str):
    path = tmp_path / "s.toml"
    path.write_text(text)
    return load_spec(path)


# ---------------------------------------------------------------------------------------------
# dotted keys


def test_a_dotted_key_walks_tables_and_arrays_by_index():
    """ "a.1.b" sets d["a"][1]["b"]; an index may also be the last part ("a.0" replaces the entry); a missing
    table on the way is created."""
    d = {"a": [{"b": 1}, {"b": 2}], "t": {"x": 1}}
    E._set_dotted(d, "a.1.b", 5)
    E._set_dotted(d, "a.0", {"b": 9})
    E._set_dotted(d, "t.y", 2)
    E._set_dotted(d, "new.deep.z", 3)
    assert d == {"a": [{"b": 9}, {"b": 5}], "t": {"x": 1, "y": 2}, "new": {"deep": {"z": 3}}}


@pytest.mark.parametrize(
    "key, missing",
    [
        ("a.2.b", "a.2"),  # index past the end, on the way
        ("a.x.b", "a.x"),  # a name where an index belongs, on the way
        ("a.-1.b", "a.-1"),  # no negative indices
        ("a.2", "a.2"),  # index past the end, last
        ("a.x", "a.x"),  # a name where an index belongs, last
        ("t.x.y", "t.x"),  # a number is no table
        ("a.0.b.c", "a.0.b"),
    ],
)
def test_a_dotted_key_that_leaves_the_config_names_where(key, missing):
    """A dotted key through an array needs an index inside it, and through a table a table: otherwise KeyError
    naming the path up to the part that does not exist, and nothing is changed."""
    d = {"a": [{"b": 1}, {"b": 2}], "t": {"x": 1}}
    with pytest.raises(KeyError) as info:
        E._set_dotted(d, key, 7)
    assert info.value.args[0] == missing
    assert d == {"a": [{"b": 1}, {"b": 2}], "t": {"x": 1}}


def test_a_set_key_with_an_array_index_reaches_the_cells_config(tmp_path):
    """`[scene.set] "material_map.1.E" = [...]` sets the second material's Young's modulus in each cell's config,
    one cell per value, and leaves the first material alone."""
    s = spec(
        tmp_path,
        '[[scene]]\nconfig = "bread"\nvariant = "baseline"\n[scene.set]\n"material_map.1.E" = [3000.0, 5000.0]\n',
    )
    a, b = E.expand(s)
    assert [c.config["material_map"][1]["E"] for c in (a, b)] == [3000.0, 5000.0]
    assert a.config["material_map"][0]["E"] == 4000.0 and a.info["set"] == "material_map.1.E=3000"


# ---------------------------------------------------------------------------------------------
# steps and cells


def test_a_dt_step_fixes_the_substep_and_a_cfl_step_makes_it_adaptive(tmp_path):
    """dt = [h] makes a cell with fixed substeps of h (adaptive off, the CFL number untouched); cfl = [c] a cell
    with adaptive substeps at CFL c (Δt stays the cap); dt cells come first. Also from a fixed-step config."""
    (tmp_path / "fixed.toml").write_text('extends = "bread"\n[sim]\nadaptive_dt = false\n')
    for name in ("bread", "fixed.toml"):
        s = spec(tmp_path, f'[[scene]]\nconfig = "{name}"\nvariant = "baseline"\ndt = [5e-4]\ncfl = [0.3]\n')
        fixed, adaptive = E.expand(s)
        assert (fixed.config["sim"]["adaptive_dt"], fixed.config["sim"]["dt"], fixed.config["sim"]["cfl"]) == (
            False,
            5e-4,
            0.4,
        )
        assert (adaptive.config["sim"]["adaptive_dt"], adaptive.config["sim"]["dt"]) == (True, 0.002)
        assert adaptive.config["sim"]["cfl"] == 0.3
        assert (fixed.info["step"], adaptive.info["step"]) == ("dt=0.0005", "cfl=0.3")


def test_cells_rescale_the_grid_and_a_step_given_with_them_wins(tmp_path):
    """cells = [32] on bread's 64³ grid of Δx = 1/64 gives Δx = 1/32 on a 32³ grid, and the fixed Δt doubles with
    Δx (the same CFL number); a dt step in the same table is applied after cells, so its value stands."""
    s = spec(tmp_path, '[[scene]]\nconfig = "bread"\nvariant = "baseline"\ncells = [32]\n')
    (cell,) = E.expand(s)
    sim = cell.config["sim"]
    assert (sim["dx"], sim["grid_shape"], sim["dt"]) == (1 / 32, [32, 32, 32], 0.004)
    s = spec(tmp_path, '[[scene]]\nconfig = "bread"\nvariant = "baseline"\ncells = [32]\ndt = [5e-4]\n')
    (cell,) = E.expand(s)
    assert (cell.config["sim"]["dx"], cell.config["sim"]["dt"]) == (1 / 32, 5e-4)


def test_apply_cells_keeps_the_box_and_floors_each_axis_at_four_cells():
    """Δx = (largest side of the box) / cells; each axis keeps its length in cells of the new Δx (rounded, at
    least 4), and a fixed Δt scales with Δx."""
    d = {"scene": "bread", "sim": {"grid": "explicit", "dx": 0.1, "grid_shape": [10, 5, 2], "dt": 1e-3}}
    E._apply_cells(d, 20, "scene[0]", "s.toml")
    assert d["sim"] == {"grid": "explicit", "dx": 0.05, "grid_shape": [20, 10, 4], "dt": 5e-4}
    d = {"scene": "bread", "sim": {"dx": 0.1, "grid_shape": [10, 6, 2], "dt": 1e-3}}
    E._apply_cells(d, 5, "scene[0]", "s.toml")
    assert (d["sim"]["dx"], d["sim"]["grid_shape"], d["sim"]["dt"]) == (0.2, [5, 4, 4], 2e-3)


def test_apply_cells_on_a_splat_file_sets_its_capture_resolution_and_refuses_a_sparse_grid(tmp_path):
    """A captured scene (a splat file) takes cells as capture.cells_across and keeps its sim table; a built-in
    scene on another grid than `explicit` is refused naming <table>.cells and the fix."""
    d = {"scene": str(tmp_path / "scan.ply"), "sim": {"grid": "sparse", "dx": 0.1}}
    E._apply_cells(d, 48, "scene[0]", "s.toml")
    assert d == {
        "scene": str(tmp_path / "scan.ply"),
        "sim": {"grid": "sparse", "dx": 0.1},
        "capture": {"cells_across": 48},
    }
    with pytest.raises(ConfigError, match=r"scene\[1\]\.cells needs an explicit grid .*set sim.grid = \"explicit\""):
        E._apply_cells({"scene": "bread", "sim": {"grid": "sparse", "dx": 0.1}}, 48, "scene[1]", "s.toml")


# ---------------------------------------------------------------------------------------------
# merging and progress


def test_a_repeated_cell_is_listed_once_with_every_label_and_counted_each_time(tmp_path):
    """Two tables that make the same cell give it once, at its first place, carrying both labels (once each even
    when a table repeats it); the progress callback counts every cell made, repeats included, against the
    spec's total, and the indices run on without gaps."""
    text = (
        '[[accuracy]]\nlabel = "dx"\ncase = ["bar"]\ncells = [16, 32]\ncfl = 0.4\n'
        '[[accuracy]]\nlabel = "cfl"\ncase = ["bar"]\ncells = [32]\ncfl = [0.2, 0.4]\n'
        '[[accuracy]]\nlabel = "dx"\ncase = ["bar"]\ncells = [16]\ncfl = 0.4\n'
    )
    seen = []
    cells = E.expand(spec(tmp_path, text), progress=lambda k, n: seen.append((k, n)))
    assert [(c.index, c.info["cells"], c.info["cfl"], c.labels) for c in cells] == [
        (0, 16, 0.4, ("dx",)),
        (1, 32, 0.4, ("dx", "cfl")),
        (2, 32, 0.2, ("cfl",)),
    ]
    assert seen == [(k, 5) for k in range(1, 6)]


def test_a_cells_repr_leaves_out_its_resolved_config(tmp_path):
    """A cell's repr (tracebacks, pytest's assertion output, a debugger) leaves out the resolved config dict —
    hundreds of entries, already named by the params' TOML text and the id — and keeps the rest."""
    (cell,) = E.expand(spec(tmp_path, '[[scene]]\nconfig = "bread"\nvariant = "baseline"\n'))
    text = repr(cell)
    assert text.startswith(f"Cell(index=0, id='{cell.id}', kind='scene', params=")
    assert ", config=" not in text and f"labels=('scene',), cost={cell.cost!r})" in text
