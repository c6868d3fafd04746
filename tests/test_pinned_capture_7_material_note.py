"""The note a capture prints for its material (`capture/materials.apply_material`): the sag under its own weight
is the strain ρ g H / E of a column of the object's fitted height H (g = 9.8 m/s²), so it grows in proportion to H
and is stated in per cent to 0.1; `capture.material = "config"` states [material] as written and changes nothing."""

from __future__ import annotations

import re

import pytest

from fracture_gs.capture.materials import PRESETS, apply_material
from fracture_gs.config import SceneConfig


def sag_percent(note: str) -> float:
    return float(re.search(r"sag under its own weight ≈ ([0-9.]+) %", note).group(1))


@pytest.mark.parametrize("name", sorted(PRESETS))
@pytest.mark.parametrize("size", [0.25, 0.5, 2.0])
def test_sag_is_rho_g_h_over_e_at_the_fitted_size(name, size):
    """Each preset's stated sag is 100·ρ·9.8·H/E to the printed 0.1 % at H = 0.25, 0.5 and 2 m (bread at 2 m:
    100 · 200 · 9.8 · 2 / 6000 = 65.3 %), whatever the size."""
    p = PRESETS[name]
    cfg = SceneConfig()
    cfg.capture.material = name
    expected = 100 * p.density * 9.8 * size / p.E
    assert sag_percent(apply_material(cfg, size)) == pytest.approx(expected, abs=0.05 + 1e-9)


def test_bread_at_two_metres_sags_sixty_five_per_cent():
    """Worked by hand: ρ = 200 kg/m³, E = 6 kPa, H = 2 m: 200 · 9.8 · 2 / 6000 = 0.6533, printed "65.3 %"."""
    cfg = SceneConfig()
    cfg.capture.material = "bread"
    assert "sag under its own weight ≈ 65.3 %" in apply_material(cfg, 2.0)


def test_config_material_is_stated_as_written_and_kept():
    """With capture.material = "config" the note states E, ρ and σ_R of [material] as written (3 significant
    digits, in Pa) and the material, the colour and the failure stretch stay as they were."""
    cfg = SceneConfig()
    cfg.capture.material = "config"
    cfg.material.E, cfg.material.density, cfg.material.sigma_R = 123456.0, 321.0, 7890.0
    before = (cfg.material.model, cfg.render.interior_rgb, cfg.render.max_stretch)
    note = apply_material(cfg, 0.5)
    assert note == "material: [material] as written (E = 1.23e+05 Pa, ρ = 321 kg/m³, σ_R = 7.89e+03 Pa)"
    assert (cfg.material.E, cfg.material.density, cfg.material.sigma_R) == (123456.0, 321.0, 7890.0)
    assert (cfg.material.model, cfg.render.interior_rgb, cfg.render.max_stretch) == before
