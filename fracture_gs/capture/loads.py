"""Loads that break a fitted object, placed from its bounding box in the simulation frame.

The fitted object's longest horizontal axis lies along x and up is +z (`fit.py`), so every load is
axis-aligned. The material of `configs/capture.toml` (a soft brittle solid, E = 6 kPa, ρ = 200 kg/m³,
σ_R = 250 Pa) and the speeds below are tuned together for an object `capture.size` = 0.5 m long:

* ``pull`` — grips over the outer 15 % of each end move apart along x at v (default 0.1 m/s) for the
  whole run, no gravity. A suddenly moving grip sends a stress wave ρ c v ≈ 130 Pa into the solid
  (below σ_R), and the quasi-static tension E · 2v t / L grows by ≈ 3.4 kPa/s between the grips, so
  the stress event latches near frame 8–10 where the cross-section is weakest. One clean tear.
* ``drop`` — gravity and a friction floor 0.2·size below the object, which starts falling at v
  (default 1 m/s): it lands at ≈ 1.7 m/s, the impact stress ρ c v ≈ 2 kPa exceeds σ_R, and the stress
  event may cut again as pieces hit (up to 8 events; bands only mark crack faces).
* ``impact`` — the object rests on a floor under gravity; the particles within 0.15·size of the
  middle of its −x end get a kick of v (default 2 m/s) along +x over the first 5 ms, like a hammer blow; the
  stress wave cracks it around the blow (up to 8 events).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import torch

from ..config import CuboidBoundary, ParticleRegion, PlaneBoundary, SceneConfig

DEFAULT_SPEED = {"pull": 0.1, "drop": 1.0, "impact": 2.0}
"""Automatic load speed per kind [m/s] at capture.size = 0.5 m (scaled with the size)."""


@dataclass
class LoadPlan:
    """What a load adds to the config: boundaries, gravity, initial velocity, provider settings, and
    how much room the grid needs below and along x."""

    boundaries: list = field(default_factory=list)
    gravity: tuple = (0.0, 0.0, 0.0)
    initial_velocity: tuple = (0.0, 0.0, 0.0)
    max_events: int = 1
    release: str = "first"
    floor: float | None = None  # z of the floor [m]
    note: str = ""


def plan_load(kind: str, lo: torch.Tensor, hi: torch.Tensor, dx: float, size: float, speed: float, duration: float):
    """The load `kind` for an object occupying [lo, hi] (simulation frame, metres)."""
    lo, hi = [float(v) for v in lo], [float(v) for v in hi]
    v = speed if speed > 0 else DEFAULT_SPEED.get(kind, 0.0) * size / 0.5
    L = hi[0] - lo[0]
    pad = 2 * dx
    if kind == "pull":
        grip = 0.15 * L
        ylo, yhi, zlo, zhi = lo[1] - pad, hi[1] + pad, lo[2] - pad, hi[2] + pad
        left = CuboidBoundary(
            lower=(lo[0] - pad, ylo, zlo), upper=(lo[0] + grip, yhi, zhi), velocity=(-v, 0.0, 0.0), end=duration
        )
        right = CuboidBoundary(
            lower=(hi[0] - grip, ylo, zlo), upper=(hi[0] + pad, yhi, zhi), velocity=(v, 0.0, 0.0), end=duration
        )
        note = f"load pull: grips on the outer 15 % of each end along x, {v:g} m/s apart each, no gravity"
        return LoadPlan(boundaries=[left, right], note=note)
    if kind == "drop":
        floor = lo[2] - 0.2 * size
        plane = PlaneBoundary(point=(0.0, 0.0, floor), normal=(0.0, 0.0, 1.0), mode="friction", friction=0.4)
        note = f"load drop: falls from {0.2 * size:.3g} m at {v:g} m/s onto a friction floor (up to 8 cracks)"
        return LoadPlan(
            boundaries=[plane],
            gravity=(0.0, 0.0, -9.8),
            initial_velocity=(0.0, 0.0, -v),
            max_events=8,
            release="none",
            floor=floor,
            note=note,
        )
    if kind == "impact":
        floor = lo[2] - 1.5 * dx
        plane = PlaneBoundary(point=(0.0, 0.0, floor), normal=(0.0, 0.0, 1.0), mode="friction", friction=0.4)
        r = 0.15 * size
        cy, cz = 0.5 * (lo[1] + hi[1]), 0.5 * (lo[2] + hi[2])
        kick = ParticleRegion(
            kind="impulse",
            lower=(lo[0] - pad, cy - r, cz - r),
            upper=(lo[0] + r, cy + r, cz + r),
            delta_v=(v, 0.0, 0.0),
            start=0.0,
            end=0.005,
        )
        note = (
            f"load impact: a {v:g} m/s kick along +x at the middle of the -x end, resting on a floor (up to 8 cracks)"
        )
        return LoadPlan(
            boundaries=[plane, kick], gravity=(0.0, 0.0, -9.8), max_events=8, release="none", floor=floor, note=note
        )
    return LoadPlan(note="load none: only the boundaries of the config")


def apply_load(cfg: SceneConfig, plan: LoadPlan) -> None:
    """Write a load plan into the config (its boundaries after the config's own)."""
    cfg.sim.boundaries = list(cfg.sim.boundaries) + plan.boundaries
    if plan.boundaries:
        cfg.sim.gravity = plan.gravity
        cfg.initial_velocity = plan.initial_velocity
        cfg.topology.max_events = plan.max_events
        cfg.topology.release = plan.release
