"""Loads that break a fitted object, placed from its bounding box in the simulation frame.

The fitted object's longest horizontal axis lies along x and up is +z (`fit.py`), so every load is
axis-aligned. The speeds below are tuned for an object `capture.size` = 0.5 m long made of a stiff preset
of `materials.py` (ceramic: E = 400 kPa, ρ = 2000 kg/m³, P-wave speed c ≈ 15.5 m/s, σ_R = 25 kPa); the soft
`bread` preset (E = 6 kPa, σ_R = 250 Pa) breaks under each of them sooner:

* ``pull`` — grips over the outer 15 % of each end move apart along x at v (default 0.1 m/s) for the
  whole run, no gravity. The quasi-static tension E · 2v t / L grows by ≈ 160 kPa/s between the grips,
  so the stress event latches near frame 16 where the cross-section is weakest. One clean tear.
* ``drop`` — gravity and a friction floor 0.2·size below the object, which starts falling at v
  (default 1 m/s): it lands at ≈ 1.7 m/s, the impact stress ρ c v ≈ 50 kPa exceeds σ_R, and the stress
  event may cut again as pieces hit (up to 8 events; bands only mark crack faces).
* ``impact`` — the object rests on a floor under gravity; the particles within 0.15·size of the
  middle of its −x end get a kick of v (default 4 m/s) along +x over the first 5 ms, like a hammer blow; the
  stress wave cracks it around the blow (up to 8 events). At 2 m/s the blow spreads into the stiff
  object before enough particles pass σ_R.
* ``shoot`` — the object rests on a friction floor (Δx/2 under its lowest particles) under gravity; a
  rigid ball of radius 0.12·size starts 2Δx clear of the middle of its −x side and flies along +x at v
  (default 1.5 m/s; 3 m/s scattered a statue) until it is past the object's far end. It pushes material out
  of its way and never
  pulls it (`SphereBoundary`): the contact stress ρ c v ≫ σ_R cracks the object where it hits and drives the
  pieces along +x (up to 8 events).
* ``crush`` — the object rests on the same floor under gravity; a plate (a 3Δx `CuboidBoundary` slab over
  its whole x–y footprint plus 0.1·size, `push` = −z so it presses without holding the object up) starts
  on its top and moves down at v (default 0.2 m/s): the compressive strain grows by v/H, so E v t / H passes
  σ_R within a few frames of contact. It stops, and stays there, when its lower face is 25 % of the
  object's height above the floor, so it never reaches the floor (up to 8 events).

`auto` (the default) picks `drop`, or `shoot` for an object standing on its captured ground (`auto_load`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import torch

from ..config import CuboidBoundary, ParticleRegion, PlaneBoundary, SceneConfig, SphereBoundary

DEFAULT_SPEED = {"pull": 0.1, "drop": 1.0, "impact": 4.0, "shoot": 1.5, "crush": 0.2}
"""Automatic load speed per kind [m/s] at capture.size = 0.5 m (scaled with the size)."""


@dataclass
class LoadPlan:
    """What a load adds to the config: boundaries, gravity, initial velocity, provider settings, and
    how much room the grid needs below, along x and around the load's own moving bodies."""

    boundaries: list = field(default_factory=list)
    gravity: tuple = (0.0, 0.0, 0.0)
    initial_velocity: tuple = (0.0, 0.0, 0.0)
    max_events: int = 1
    release: str = "first"
    floor: float | None = None  # z of the floor [m]
    room: tuple | None = None  # (lower, upper) corners the load's own bodies sweep, which the grid must hold [m]
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
    if kind == "shoot":
        return _shoot(lo, hi, dx, size, v, duration)
    if kind == "crush":
        return _crush(lo, hi, dx, size, v, duration)
    return LoadPlan(note="load none: only the boundaries of the config")


def _resting(lo: list, dx: float) -> PlaneBoundary:
    """A friction floor Δx/2 under the object's lowest particles: the nodes below them are behind it from
    the start, so the object rests on it instead of falling onto it."""
    return PlaneBoundary(point=(0.0, 0.0, lo[2] - 0.5 * dx), normal=(0.0, 0.0, 1.0), mode="friction", friction=0.4)


def _shoot(lo: list, hi: list, dx: float, size: float, v: float, duration: float) -> LoadPlan:
    """A ball of radius 0.12·size, 2Δx clear of the −x side at mid-height, flying along +x at v until
    it is 2Δx past the object's +x end; the room holds its path during the run."""
    floor = _resting(lo, dx)
    r = 0.12 * size
    centre = (lo[0] - r - 2 * dx, 0.5 * (lo[1] + hi[1]), 0.5 * (lo[2] + hi[2]))
    end = (hi[0] + r + 2 * dx - centre[0]) / v
    ball = SphereBoundary(center=centre, radius=r, velocity=(v, 0.0, 0.0), start=0.0, end=end)
    reach = centre[0] + v * min(end, duration)
    room = ((centre[0] - r, centre[1] - r, centre[2] - r), (reach + r, centre[1] + r, centre[2] + r))
    note = (
        f"load shoot: a rigid ball (radius {r:.3g} m) flies along +x at {v:g} m/s into the middle of the -x side "
        f"and past the object by t = {end:.3g} s; it rests on a friction floor (up to 8 cracks)"
    )
    return LoadPlan(
        boundaries=[floor, ball],
        gravity=(0.0, 0.0, -9.8),
        max_events=8,
        release="none",
        floor=floor.point[2],
        room=room,
        note=note,
    )


def _crush(lo: list, hi: list, dx: float, size: float, v: float, duration: float) -> LoadPlan:
    """A 3Δx-thick plate over the footprint plus 0.1·size, its lower face Δx/2 above the object's top,
    moving down at v until the face is 25 % of the object's height above the floor, then held there."""
    floor = _resting(lo, dx)
    height = hi[2] - lo[2]
    margin = 0.1 * size
    face, stop = hi[2] + 0.5 * dx, floor.point[2] + 0.25 * height
    end = (face - stop) / v
    lower, upper = (lo[0] - margin, lo[1] - margin, face), (hi[0] + margin, hi[1] + margin, face + 3 * dx)
    down = (0.0, 0.0, -1.0)  # a pusher: it presses, never holds the object up against its own weight
    press = CuboidBoundary(lower=lower, upper=upper, velocity=(0.0, 0.0, -v), start=0.0, end=end, push=down)
    held = CuboidBoundary(
        lower=(lower[0], lower[1], stop), upper=(upper[0], upper[1], stop + 3 * dx), start=end, push=down
    )
    where = f"{stop - floor.point[2]:.3g} m above the floor (25 % of the object's height) at t = {end:.3g} s"
    what = (
        f"it stops {where} and stays" if end <= duration else f"{v * duration:.3g} m in this run, it would stop {where}"
    )
    note = (
        f"load crush: a plate over the whole top presses down at {v:g} m/s on the object, which rests on a friction "
        f"floor: {what} (up to 8 cracks)"
    )
    return LoadPlan(
        boundaries=[floor, press, held],
        gravity=(0.0, 0.0, -9.8),
        max_events=8,
        release="none",
        floor=floor.point[2],
        room=(lower, upper),
        note=note,
    )


def auto_load(lo, hi, grounded: bool = False) -> tuple[str, str]:
    """(load, why) for `capture.load = "auto"` from the fitted object's box [lo, hi] and whether it stands on a
    ground kept static (`ground.find_ground`). A fall is what breaks real objects, needs no grips placed on a
    shape the tool does not know, and lets the shape decide where it breaks: `drop`. An object standing on its
    captured ground cannot fall through it, so a ball thrown at its side breaks it where it stands: `shoot`
    (at 1.5 m/s it broke the seal statue into 8 pieces that separate; at 3 m/s it scattered them, and a hammer
    blow, `impact`, cracked it without separating the pieces). A ball at mid-height of a tall slender object
    with no ground was tried too: it scattered a guitar out of the frame (edge strength 0.72 of frame 0,
    against 0.87 for the drop)."""
    height, width = float(hi[2] - lo[2]), float(max(hi[0] - lo[0], hi[1] - lo[1]))
    if grounded:
        return "shoot", "it stands on its captured ground, which stays static: a fall would sink it through it"
    return "drop", f"a fall breaks any shape without grips ({height / width:.1f}× as tall as wide)"


def apply_load(cfg: SceneConfig, plan: LoadPlan) -> None:
    """Write a load plan into the config (its boundaries after the config's own)."""
    cfg.sim.boundaries = list(cfg.sim.boundaries) + plan.boundaries
    if plan.boundaries:
        cfg.sim.gravity = plan.gravity
        cfg.initial_velocity = plan.initial_velocity
        cfg.topology.max_events = plan.max_events
        cfg.topology.release = plan.release
