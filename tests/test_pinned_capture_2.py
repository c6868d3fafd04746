"""Pinned rules of the capture package, round two: the starter TOML's field documentation and its wrapping,
the sampling and grid notes' millimetres, the named up axes, the resolution budgets' most cells across and
the notes the material presets print.

Unit-level calls on small synthetic inputs; one test resolves a small trainer-like PLY (no simulation runs).
"""

from __future__ import annotations

import re

import pytest
import torch
from trainer_ply import write_trainer_ply

from fracture_gs.capture import resolution, starter
from fracture_gs.capture.fit import detect_up
from fracture_gs.capture.materials import apply_material
from fracture_gs.capture.resolution import choose
from fracture_gs.capture.sample import sample
from fracture_gs.capture.scene import resolve
from fracture_gs.config import CaptureConfig, SceneConfig
from fracture_gs.io.config import load_config
from fracture_gs.io.gaussian_set import GaussianSet

pytestmark = pytest.mark.usefixtures("one_thread")


# ---------------------------------------------------------------------------------------------
# starter TOML: field documentation and its wrapping


def test_starter_comments_carry_the_fields_own_docstring():
    """`commented` puts the docstring written under a config field in config.py above that key's line: the
    capture size's comment names its unit, and an unknown key gets no comment."""
    text = starter.commented("[capture]\nsize = 0.5\nnot_a_key = 1\n")
    lines = text.splitlines()
    at = lines.index("size = 0.5")
    block = []
    for line in reversed(lines[:at]):
        if not line.startswith("# "):
            break
        block.insert(0, line[2:])
    assert block, "the documented key capture.size has no comment above it"
    doc = " ".join(block)
    assert "[m]" in doc or "metre" in doc, doc
    assert lines[lines.index("not_a_key = 1") - 1] == "size = 0.5"


def test_short_doc_stays_on_one_comment_line(monkeypatch):
    """Words are packed greedily: a short paragraph is one comment line, not one word per line."""
    monkeypatch.setattr(starter, "field_docs", lambda: {("SceneConfig", "name"): "the scene's name as shown"})
    text = starter.commented('name = "x"\n')
    assert text == '# the scene\'s name as shown\nname = "x"\n'


def test_a_98_character_paragraph_fits_one_comment_line(monkeypatch):
    """A comment line holds up to 98 characters of text (100 columns with '# '): two words making exactly 98
    characters stay on one line."""
    doc = "a" * 48 + " " + "b" * 49  # 98 characters
    monkeypatch.setattr(starter, "field_docs", lambda: {("SceneConfig", "name"): doc})
    text = starter.commented('name = "x"\n')
    assert text.splitlines() == ["# " + doc, 'name = "x"']


# ---------------------------------------------------------------------------------------------
# notes in millimetres


def test_sample_note_states_the_voxel_in_millimetres():
    """Sampling a dense surface on 10 mm voxels keeps one particle per voxel and its note says '10 mm voxel'
    (spacing [m] × 1000)."""
    g = torch.Generator().manual_seed(0)
    n = 3000
    x = 0.04 * torch.rand(n, 3, generator=g)  # a 4 cm cube: at most 5³ voxels of 1 cm
    quats = torch.zeros(n, 4)
    quats[:, 0] = 1.0
    gs = GaussianSet(x, quats, torch.full((n, 3), 0.002), torch.rand(n, generator=g), torch.zeros(n, 1, 3))
    carried, note = sample(gs, 0.01)
    assert carried.carrier is not None
    assert "one per 10 mm voxel" in note, note


@pytest.fixture(scope="module")
def small_ply(tmp_path_factory):
    return write_trainer_ply(tmp_path_factory.mktemp("small"), n=1500)


def test_auto_grid_note_states_the_cell_in_millimetres(small_ply):
    """With 16 cells across the 0.5 m object, the automatic grid's note reads its shape and cells of
    0.5 / 16 m = 31.25 mm ('31.2 mm'), and the shape is the one written into sim.grid_shape."""
    ply, _ = small_ply
    cfg = load_config(ply)
    cfg.capture.cells_across, cfg.capture.load, cfg.fill_interior = 16, "none", False
    cap = resolve(cfg)
    notes = [n for n in cap.notes if n.startswith("grid ")]
    assert len(notes) == 1, cap.notes
    m = re.fullmatch(r"grid (\d+)×(\d+)×(\d+) cells of ([0-9.e+]+) mm", notes[0])
    assert m, notes[0]
    assert tuple(int(v) for v in m.groups()[:3]) == tuple(cap.cfg.sim.grid_shape)
    assert float(m.group(4)) == pytest.approx(1e3 * 0.5 / 16, rel=0.01)


# ---------------------------------------------------------------------------------------------
# named up axes


@pytest.mark.parametrize(
    "name, vector",
    [("+x", (1, 0, 0)), ("-x", (-1, 0, 0)), ("+y", (0, 1, 0)),
     ("-y", (0, -1, 0)), ("+z", (0, 0, 1)), ("-z", (0, 0, -1))],
)  # fmt: skip
def test_named_up_axis_is_the_unit_vector_of_that_axis(name, vector):
    """`capture.up = "±x/±y/±z"` is the unit vector along that axis with that sign, whatever the cameras say."""
    up, note = detect_up(CaptureConfig(up=name), [])
    assert torch.equal(up, torch.tensor(vector, dtype=torch.float64))
    assert name in note


# ---------------------------------------------------------------------------------------------
# resolution budgets: the most cells across


@pytest.mark.parametrize(
    "device, quality, cells",
    [("cpu", "draft", 24), ("cpu", "default", 44), ("cpu", "fine", 64), ("cuda:0", "draft", 64),
     ("cuda:0", "default", 128), ("cuda:0", "fine", 256)],
)  # fmt: skip
def test_thin_object_gets_the_most_cells_of_its_quality(monkeypatch, device, quality, cells):
    """An object with 1 mm thin parts would want 1000 cells across; it gets the quality's most cells on its
    device (CPU: 24 / 44 / 64, GPU: 64 / 128 / 256 for draft / default / fine) when its particles fit the budget
    (the probe's measurement is given: a solid of 10⁻⁶ of the size cube)."""
    monkeypatch.setattr(resolution, "probe", lambda *a, **k: (0.001, 1e-6))
    gs = GaussianSet(torch.rand(20, 3), torch.tensor([[1.0, 0, 0, 0]]).repeat(20, 1), torch.full((20, 3), 0.01),
                     torch.full((20,), 0.9), torch.zeros(20, 1, 3))  # fmt: skip
    res = choose(gs, CaptureConfig(quality=quality), device)
    assert res.cells == cells
    assert res.dx == pytest.approx(0.5 / cells)


# ---------------------------------------------------------------------------------------------
# material presets as the user reads them


@pytest.mark.parametrize(
    "name, constants",
    [
        ("ceramic", "E = 400 kPa, ρ = 2000 kg/m³, σ_R = 25 kPa; wave speed 15.5 m/s, sag under its own weight ≈ 2.5 %"),
        ("wood", "E = 150 kPa, ρ = 600 kg/m³, σ_R = 10 kPa; wave speed 18.3 m/s, sag under its own weight ≈ 2.0 %"),
        ("plant", "E = 60 kPa, ρ = 500 kg/m³, σ_R = 6 kPa; wave speed 12.7 m/s, sag under its own weight ≈ 4.1 %"),
        ("bread", "E = 6 kPa, ρ = 200 kg/m³, σ_R = 0.25 kPa; wave speed 6.4 m/s, sag under its own weight ≈ 16.3 %"),
    ],
)
def test_preset_note_states_the_preset_constants(name, constants):
    """Choosing a preset prints its constants, with the wave speed c = √((λ + 2μ)/ρ) and sag ρ g H / E at
    H = 0.5 m computed from them: ceramic 400 kPa / 2000 kg/m³ / 25 kPa, wood 150 kPa / 600 kg/m³ / 10 kPa,
    plant 60 kPa / 500 kg/m³ / 6 kPa (light, dry plant tissue), bread 6 kPa / 200 kg/m³ / 0.25 kPa."""
    cfg = SceneConfig()
    cfg.capture.material = name
    note = apply_material(cfg, 0.5)
    assert constants in note, note
