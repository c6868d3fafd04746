"""Pinned rules of a material preset applied to a capture (`capture.materials.apply_material`), round eight: the
preset's E, ν, ρ and σ_R go into [material] with the fixed-corotated model, its colour into [render], the failure
stretch 1 + 4 σ_R / E into render.max_stretch, capture.material becomes "config"; and the note states E and σ_R in
kPa (E to the kPa), ρ, the P-wave speed √((λ + 2μ)/ρ) to 0.1 m/s and the sag ρ g H / E in per cent.

Every number below is worked by hand at H = 1 m (g = 9.8 m/s²), e.g. ceramic: λ = μ = 160 kPa, so
c = √(480 000 / 2000) = √240 = 15.49 m/s; sag 2000 · 9.8 / 400 000 = 4.9 %.
"""

from __future__ import annotations

import pytest

from fracture_gs.capture import materials
from fracture_gs.capture.materials import Preset, apply_material
from fracture_gs.config import SceneConfig

TAIL = "(set capture.material: ceramic, wood, plant, bread or config)"
NOTES = {
    "ceramic": "material ceramic (stiff and brittle: breaks into shards): E = 400 kPa, ρ = 2000 kg/m³, σ_R = 25 kPa; "
    "wave speed 15.5 m/s, sag under its own weight ≈ 4.9 % ",
    "wood": "material wood (stiff, splits along the load): E = 150 kPa, ρ = 600 kg/m³, σ_R = 10 kPa; "
    "wave speed 18.3 m/s, sag under its own weight ≈ 3.9 % ",  # λ + 2μ = 201 923 Pa; / 600 → 18.35
    "plant": "material plant (bends, then snaps): E = 60 kPa, ρ = 500 kg/m³, σ_R = 6 kPa; "
    "wave speed 12.7 m/s, sag under its own weight ≈ 8.2 % ",  # λ + 2μ = 80 769 Pa; / 500 → 12.71
    "bread": "material bread (soft: stretches and tears): E = 6 kPa, ρ = 200 kg/m³, σ_R = 0.25 kPa; "
    "wave speed 6.4 m/s, sag under its own weight ≈ 32.7 % ",  # λ + 2μ = 8 077 Pa; / 200 → 6.355
}
WRITTEN = {  # E [Pa], ν, ρ [kg/m³], σ_R [Pa], max_stretch = 1 + 4 σ_R / E
    "ceramic": (4.0e5, 0.25, 2000.0, 2.5e4, 1.25),
    "wood": (1.5e5, 0.30, 600.0, 1.0e4, 1 + 4 / 15),
    "plant": (6.0e4, 0.30, 500.0, 6.0e3, 1.4),
    "bread": (6.0e3, 0.30, 200.0, 2.5e2, 1 + 1 / 6),
}


@pytest.mark.parametrize("name", sorted(NOTES))
def test_each_preset_is_written_into_the_config_and_stated_in_its_note(name):
    """The note reads the preset's look, E and σ_R in kPa, ρ, the wave speed and the sag at 1 m exactly as worked
    by hand; [material] holds the preset (fixed-corotated), [render] its colour and failure stretch, and the
    capture says "config" so a rerun keeps what was written."""
    cfg = SceneConfig()
    cfg.capture.material = name
    assert apply_material(cfg, 1.0) == NOTES[name] + TAIL
    E, nu, rho, sigma, stretch = WRITTEN[name]
    m = cfg.material
    assert (m.model, m.E, m.nu, m.density, m.sigma_R) == ("fixed_corotated", E, nu, rho, sigma)
    assert cfg.render.max_stretch == pytest.approx(stretch, rel=1e-15)
    assert cfg.render.interior_rgb == materials.PRESETS[name].interior_rgb
    assert cfg.capture.material == "config"


def test_the_note_converts_any_presets_moduli_to_kilopascals(monkeypatch):
    """A preset of E = 1 MPa and σ_R = 50 kPa (not one of the four: the conversion is checked where rounding
    would show it) reads "E = 1000 kPa" and "σ_R = 50 kPa"; ν = 0.25 and ρ = 4000 give λ = μ = 400 kPa and
    c = √(1.2 MPa / 4000) = √300 = 17.3 m/s; the sag at 1 m is 4000 · 9.8 / 10⁶ = 3.9 %."""
    monkeypatch.setitem(materials.PRESETS, "steel", Preset(1.0e6, 0.25, 4000.0, 5.0e4, (0.5, 0.5, 0.5), "a test"))
    cfg = SceneConfig()
    cfg.capture.material = "steel"
    assert apply_material(cfg, 1.0) == (
        "material steel (a test): E = 1000 kPa, ρ = 4000 kg/m³, σ_R = 50 kPa; wave speed 17.3 m/s, sag under its "
        "own weight ≈ 3.9 % " + TAIL
    )
