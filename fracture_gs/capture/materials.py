"""Material presets for a captured object (`capture.material`): stiff enough not to sag, brittle enough to break.

An explicit MPM step is bounded by the CFL condition Δt ≤ cfl·Δx / (c + |v|), with c the P-wave speed
c = √((λ + 2μ)/ρ). A real ceramic (c ≈ 5 km/s) would need ~10⁵ substeps a frame, so each preset takes the
stiffest value a run can afford, c ≈ 13–18 m/s (the soft `bread` keeps the built-in loaf's 6 m/s). What that
costs and keeps, at the fitted size of 0.5 m:

* sag under its own weight: strain ≈ ρ g H / E ≈ g H / c² ≈ 1–2.5 % (plant 4 %; a 6 kPa jelly sags 40 %);
* strength: σ_R above 2× the self-weight stress ρ g H of a 0.5 m tall object, so it stands, and below the
  impact stress ρ c v of a 1.5 m/s drop or a 3 m/s projectile, so a load breaks it;
* the interior colour shown on crack faces (`render.interior_color = "material"`).

Δt then follows from the CFL bound of the chosen stiffness (`sim.adaptive_dt`, each frame's largest stable
substep below `sim.dt`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class Preset:
    """One material preset (SI units)."""

    E: float  # Young's modulus [Pa]
    nu: float  # Poisson ratio
    density: float  # [kg/m³]
    sigma_R: float  # fracture strength for the stress event provider [Pa]
    interior_rgb: tuple  # colour of the material inside, RGB in [0, 1]
    look: str  # what it does, for the note line

    @property
    def wave_speed(self) -> float:
        """P-wave speed [m/s]."""
        return wave_speed(self.E, self.nu, self.density)


def wave_speed(E: float, nu: float, density: float) -> float:
    """P-wave speed c = √((λ + 2μ)/ρ) [m/s] of Young's modulus E [Pa], Poisson ratio ν and density ρ [kg/m³]."""
    lam, mu = E * nu / ((1 + nu) * (1 - 2 * nu)), E / (2 * (1 + nu))
    return math.sqrt((lam + 2 * mu) / density)


PRESETS = {
    "ceramic": Preset(4.0e5, 0.25, 2000.0, 2.5e4, (0.93, 0.91, 0.86), "stiff and brittle: breaks into shards"),
    "wood": Preset(1.5e5, 0.30, 600.0, 1.0e4, (0.80, 0.66, 0.46), "stiff, splits along the load"),
    "plant": Preset(6.0e4, 0.30, 500.0, 6.0e3, (0.55, 0.70, 0.35), "bends, then snaps"),
    "bread": Preset(6.0e3, 0.30, 200.0, 2.5e2, (0.95, 0.87, 0.68), "soft: stretches and tears"),
}
"""The presets, tuned at capture.size = 0.5 m."""


def apply_material(cfg, size: float) -> str:
    """Write the preset `cfg.capture.material` into [material] and the interior colour into [render]; returns
    the note line (wave speed, sag, the substep it needs at the run's Δx). `config` keeps [material] as
    written. The resolved config says `config` so that a rerun keeps what was written out."""
    name = cfg.capture.material
    if name == "config":
        m = cfg.material
        return f"material: [material] as written (E = {m.E:.3g} Pa, ρ = {m.density:g} kg/m³, σ_R = {m.sigma_R:.3g} Pa)"
    p = PRESETS[name]
    m = cfg.material
    m.model, m.E, m.nu, m.density, m.sigma_R = "fixed_corotated", p.E, p.nu, p.density, p.sigma_R
    cfg.render.interior_rgb = p.interior_rgb
    cfg.render.max_stretch = 1.0 + 4.0 * p.sigma_R / p.E  # beyond its failure strain it would have broken
    cfg.capture.material = "config"
    sag = p.density * 9.8 * size / p.E
    return (
        f"material {name} ({p.look}): E = {p.E / 1e3:.0f} kPa, ρ = {p.density:g} kg/m³, σ_R = {p.sigma_R / 1e3:.3g} "
        f"kPa; wave speed {p.wave_speed:.1f} m/s, sag under its own weight ≈ {100 * sag:.1f} % "
        f"(set capture.material: ceramic, wood, plant, bread or config)"
    )


def substep_note(cfg) -> str:
    """The CFL substep of the run's material at its Δx, and substeps per frame."""
    m = cfg.material
    c = wave_speed(m.E, m.nu, m.density)
    dt = cfg.sim.cfl * cfg.sim.dx / c
    return f"Δt ≤ {dt * 1e3:.3g} ms from the CFL bound (wave speed {c:.1f} m/s at Δx = {cfg.sim.dx * 1e3:.3g} mm): " + (
        f"about {math.ceil(cfg.frame_dt / min(dt, cfg.sim.dt))} substeps a frame"
    )


def apply_regions(cfg, gs, source: str = "") -> str:
    """Label the Gaussians of `gs` (scene coordinates) inside each of `cfg.capture.regions` REGION_LABEL + i and
    give each label a `material_map` entry with its preset (replacing one of the same label, so resolving a
    written config again changes nothing); returns the note line. A region left with none of the object's
    Gaussians (outside it, or covered by a later region) would change nothing: SceneError naming it (`source`:
    "<file>: ")."""
    import torch

    from ..config import REGION_LABEL, MaterialMapEntry
    from ..errors import SceneError

    x = gs.means.detach().to(torch.float64)
    for i, r in enumerate(cfg.capture.regions):
        lo, hi = torch.tensor(r.lower, dtype=torch.float64), torch.tensor(r.upper, dtype=torch.float64)
        inside = ((x >= lo) & (x <= hi)).all(1).to(gs.labels.device)
        label, p = REGION_LABEL + i, PRESETS[r.material]
        gs.labels[inside] = label
        entry = MaterialMapEntry(label, "fixed_corotated", p.E, p.nu, p.density, sigma_R=p.sigma_R)
        cfg.material_map = [e for e in cfg.material_map if e.label != label] + [entry]
    parts = []
    for i, r in enumerate(cfg.capture.regions):
        count = int((gs.labels == REGION_LABEL + i).sum())
        if count == 0:
            raise SceneError(
                f"{source}capture.regions[{i}] (lower = {list(r.lower)}, upper = {list(r.upper)}) holds none of the "
                f"object's {len(gs)} Gaussians (or a later region covers all of them), so its material {r.material!r} "
                "would change nothing; move the box over the part it names (scene coordinates), or remove it."
            )
        parts.append(f"{count} Gaussians {r.material} (label {REGION_LABEL + i})")
    return "material regions: " + ", ".join(parts)
