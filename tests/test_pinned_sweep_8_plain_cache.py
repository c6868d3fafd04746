"""Pinned rules of one scene cell's config (`fracture_gs.sweep.expansion.scene_config`) and the cache of base configs
it may share with the other cells of an expansion (`plain`): called on its own (no cache, the default) it gives the
same config as inside `expand`; with a cache, the base config is kept once per (config name, preset), and one
cell's overrides never leak into the cached base that the next cell starts from.

Unit-level: configs are resolved and validated, nothing is simulated.
"""

from __future__ import annotations

from fracture_gs.io.config import config_to_dict
from fracture_gs.sweep import expansion as E
from fracture_gs.sweep.spec import load_spec

SPEC = (
    '[[scene]]\nconfig = "bread"\nvariant = "baseline"\npreset = "paper"\n[scene.material]\nE = [1000.0, 3000.0]\n'
    '[[scene]]\nconfig = "bread"\nvariant = "baseline"\n'
)


def _spec(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text(SPEC)
    return load_spec(path)


def test_a_cell_made_alone_equals_the_cell_made_by_the_expansion(tmp_path):
    """scene_config without a cache (plain = None) gives, for each of the three cells, exactly the resolved config
    `expand` made for it: the paper preset's Δx = 1/128 and the cell's E on the first table, the file's own Δx and E
    on the second."""
    spec = _spec(tmp_path)
    cells = E.expand(spec)
    assert len(cells) == 3
    base = E._base_config(spec, "scene[0]", "bread", {})
    first, second = spec.scenes
    made = [
        E.scene_config(spec, "scene[0]", "bread", base, first, None, None, {"material.E": 1000.0}, 0, "baseline"),
        E.scene_config(spec, "scene[0]", "bread", base, first, None, None, {"material.E": 3000.0}, 0, "baseline"),
        E.scene_config(spec, "scene[1]", "bread", base, second, None, None, {}, 0, "baseline"),
    ]
    assert [config_to_dict(c) for c in made] == [c.config for c in cells]
    assert [(c.sim.dx, c.material.E) for c in made[:2]] == [(1 / 128, 1000.0), (1 / 128, 3000.0)]
    assert (made[2].sim.dx, made[2].material.E) == (base.sim.dx, base.material.E) and base.sim.dx == 1 / 64


def test_the_shared_cache_holds_one_base_per_name_and_preset_and_no_overrides(tmp_path):
    """With a shared cache, cells of the same (name, preset) reuse one stored base: after the three cells it holds
    exactly ('bread', 'paper') and ('bread', None); the stored paper base still has the base material's E (not a
    cell's 1000 or 3000) and Δx = 1/128, and a cell made after another's override is the same as one made first."""
    spec = _spec(tmp_path)
    base = E._base_config(spec, "scene[0]", "bread", {})
    first, second = spec.scenes
    plain: dict = {}
    a = E.scene_config(spec, "scene[0]", "bread", base, first, None, None, {"material.E": 1000.0}, 0, "baseline", plain)
    b = E.scene_config(spec, "scene[0]", "bread", base, first, None, None, {"material.E": 3000.0}, 0, "baseline", plain)
    c = E.scene_config(spec, "scene[1]", "bread", base, second, None, None, {}, 0, "baseline", plain)
    assert sorted(plain, key=str) == [("bread", "paper"), ("bread", None)]
    assert plain[("bread", "paper")]["material"]["E"] == base.material.E != 3000.0
    assert plain[("bread", "paper")]["sim"]["dx"] == 1 / 128 and plain[("bread", None)]["sim"]["dx"] == 1 / 64
    again = E.scene_config(spec, "scene[0]", "bread", base, first, None, None, {"material.E": 1000.0}, 0, "baseline")
    assert config_to_dict(a) == config_to_dict(again) and (a.material.E, b.material.E) == (1000.0, 3000.0)
    alone = E.scene_config(spec, "scene[1]", "bread", base, second, None, None, {}, 0, "baseline")
    assert config_to_dict(c) == config_to_dict(alone)
