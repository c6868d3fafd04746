"""`Particles`: MLS-MPM particle state as torch tensors (float32 on the simulation device)."""

from __future__ import annotations

from typing import Optional

import torch

from ..config import MATERIALS, MaterialConfig, SceneConfig
from ..errors import ArgumentError, SimulationError
from .physics.constitutive import MATERIAL_IDS, dp_alpha


def _per_particle(value, n: int, name: str, device) -> torch.Tensor:
    t = torch.as_tensor(value, dtype=torch.float32, device=device)
    if t.ndim == 0:
        t = t.expand(n).clone()
    if t.shape != (n,):
        raise SimulationError(f"Particles.{name} has shape {tuple(t.shape)}; expected a scalar or [{n}]")
    return t.contiguous()


def _positive(t: torch.Tensor, zero: bool = False) -> torch.Tensor:
    """Every entry finite and > 0 (or >= 0 with `zero`)."""
    return (torch.isfinite(t) & ((t >= 0) if zero else (t > 0))).all()


class Particles:
    """Particle state shared zero-copy with the Warp kernels.

    Kinematics x, v, C, F; rest mass and volume; per-particle material (model id, E, ν, yield
    stress, hardening, Drucker–Prager α, fracture strength σ_R); topology labels `fragment`
    (o_p, −1 before the latch) and `band` (γ_p). `interior` marks fill particles (not drawn).
    """

    def __init__(
        self,
        x: torch.Tensor,  # [N, 3]
        v: Optional[torch.Tensor] = None,  # [N, 3]
        mass: Optional[torch.Tensor] = None,  # [N]
        volume: Optional[torch.Tensor] = None,  # [N] rest volume V⁰
        F: Optional[torch.Tensor] = None,  # [N, 3, 3] (identity if None)
        C: Optional[torch.Tensor] = None,  # [N, 3, 3] (zero if None)
        E=1e5,  # scalar or [N] Young's modulus [Pa]
        nu=0.3,  # scalar or [N] Poisson ratio
        material="fixed_corotated",  # name, or [N] int ids (MATERIAL_IDS)
        yield_stress=1e4,  # scalar or [N] [Pa]
        hardening=0.0,  # scalar or [N]
        friction_angle=30.0,  # degrees, scalar or [N] (Drucker–Prager)
        sigma_R=float("inf"),  # scalar or [N] fracture strength [Pa]
        interior: Optional[torch.Tensor] = None,  # [N] bool
    ):
        if not torch.is_tensor(x) or x.ndim != 2 or x.shape[1] != 3:
            raise SimulationError("Particles.x must be a tensor of shape [N, 3]")
        n = x.shape[0]
        if n == 0:
            raise SimulationError("Particles.x is empty; a simulation needs at least one particle")
        dev = x.device
        self.x = x.detach().to(torch.float32).contiguous().clone()
        self.v = self._vec(v, n, "v", dev)
        self.mass = _per_particle(1.0 if mass is None else mass, n, "mass", dev)
        self.volume = _per_particle(1.0 if volume is None else volume, n, "volume", dev)
        self.F = self._mat(F, n, "F", dev, identity=True)
        self.C = self._mat(C, n, "C", dev, identity=False)
        self.E = _per_particle(E, n, "E", dev)
        self.nu = _per_particle(nu, n, "nu", dev)
        self.material = self._material_ids(material, n, dev)
        self.yield_stress = _per_particle(yield_stress, n, "yield_stress", dev)
        self.hardening = _per_particle(hardening, n, "hardening", dev)
        self.alpha = dp_alpha(_per_particle(friction_angle, n, "friction_angle", dev)).contiguous()
        self.sigma_R = _per_particle(sigma_R, n, "sigma_R", dev)
        self.fragment = torch.full((n,), -1, dtype=torch.int32, device=dev)
        self.band = torch.zeros(n, dtype=torch.int32, device=dev)
        self.interior = (
            torch.zeros(n, dtype=torch.bool, device=dev) if interior is None else interior.to(dev, torch.bool)
        )
        self.validate()

    @staticmethod
    def _vec(t, n, name, dev):
        if t is None:
            return torch.zeros(n, 3, dtype=torch.float32, device=dev)
        if tuple(t.shape) != (n, 3):
            raise SimulationError(f"Particles.{name} has shape {tuple(t.shape)}; expected [{n}, 3]")
        return t.detach().to(dev, torch.float32).contiguous().clone()

    @staticmethod
    def _mat(t, n, name, dev, identity):
        if t is None:
            eye = torch.eye(3, dtype=torch.float32, device=dev) if identity else torch.zeros(3, 3, device=dev)
            return eye.expand(n, 3, 3).contiguous()
        if tuple(t.shape) != (n, 3, 3):
            raise SimulationError(f"Particles.{name} has shape {tuple(t.shape)}; expected [{n}, 3, 3]")
        return t.detach().to(dev, torch.float32).contiguous().clone()

    @staticmethod
    def _material_ids(material, n, dev):
        if isinstance(material, str):
            if material not in MATERIAL_IDS:
                raise SimulationError(f"material '{material}' is unknown; use one of {', '.join(MATERIALS)}")
            return torch.full((n,), MATERIAL_IDS[material], dtype=torch.int32, device=dev)
        ids = torch.as_tensor(material, dtype=torch.int32, device=dev)
        if ids.shape != (n,) or ids.min() < 0 or ids.max() >= len(MATERIAL_IDS):
            raise SimulationError(f"Particles.material must be a model name or [{n}] ids in 0..{len(MATERIAL_IDS) - 1}")
        return ids.contiguous()

    def validate(self):
        """One-sentence errors for physically invalid parameters."""
        checks = [
            (torch.isfinite(self.x).all(), "x contains NaN or inf; fix the input positions"),
            (torch.isfinite(self.v).all(), "v contains NaN or inf; fix the initial velocities"),
            (torch.isfinite(self.C).all(), "C contains NaN or inf; fix the initial affine velocities"),
            (torch.isfinite(self.F).all(), "F contains NaN or inf; fix the initial deformation gradients"),
            (_positive(self.E), "E must be a finite number > 0 for every particle (Young's modulus in Pa)"),
            (((self.nu >= 0) & (self.nu < 0.5)).all(), "nu must lie in [0, 0.5) for every particle"),
            (_positive(self.mass), "mass must be a finite number > 0 for every particle (kg)"),
            (_positive(self.volume), "volume must be a finite number > 0 for every particle (m³)"),
            (_positive(self.alpha, zero=True), "friction_angle must lie in [0, 90) degrees for every particle"),
            (_positive(self.hardening, zero=True), "hardening must be a finite number >= 0 for every particle"),
            ((~torch.isnan(self.sigma_R)).all() & (self.sigma_R > 0).all(), "sigma_R must be > 0 (inf: never breaks)"),
            (
                (~torch.isnan(self.yield_stress)).all() & (self.yield_stress > 0).all(),
                "yield_stress must be > 0 (inf: never yields)",
            ),
        ]
        for ok, msg in checks:
            if not bool(ok):
                raise SimulationError(f"Particles.{msg}")
        tensors = [getattr(self, k) for k in self.TENSORS]
        if len({t.device for t in tensors}) != 1:
            raise SimulationError("Particles tensors live on different devices; move them all to one device")

    TENSORS = (
        "x",
        "v",
        "C",
        "F",
        "mass",
        "volume",
        "E",
        "nu",
        "material",
        "yield_stress",
        "hardening",
        "alpha",
        "sigma_R",
        "fragment",
        "band",
        "interior",
    )

    def __len__(self) -> int:
        return self.x.shape[0]

    @property
    def device(self) -> torch.device:
        return self.x.device

    def to(self, device) -> Particles:
        """Move every tensor (in place) to `device`; returns self."""
        for k in self.TENSORS:
            setattr(self, k, getattr(self, k).to(device).contiguous())
        return self

    def clone(self) -> Particles:
        out = object.__new__(Particles)
        for k in self.TENSORS:
            setattr(out, k, getattr(self, k).clone())
        return out

    def permute(self, order: torch.Tensor) -> None:
        """Reorder every particle tensor in place (e.g. into grid-cell order)."""
        for k in self.TENSORS:
            getattr(self, k).copy_(getattr(self, k)[order])

    @staticmethod
    def from_gaussians(gs, cfg: SceneConfig, dx: Optional[float] = None) -> Particles:
        """Particles from a GaussianSet: x = means, volume = Δx³ / (particles in its cell) (as in
        PhysGaussian), mass = ρ V, material parameters from the config's defaults and its
        per-label material map."""
        from ..io.gaussian_set import GaussianSet

        if not isinstance(gs, GaussianSet):
            raise ArgumentError(
                f"Particles.from_gaussians: gs must be a GaussianSet, got {type(gs).__name__}; build one with "
                "fracture_gs.assets.build, fracture_gs.io.load_ply or fracture_gs.io.GaussianSet(...)."
            )
        if not isinstance(cfg, SceneConfig):
            raise ArgumentError(
                f"Particles.from_gaussians: cfg must be a SceneConfig, got {type(cfg).__name__}; load one with "
                "fracture_gs.io.load_config."
            )
        dx = float(dx or cfg.sim.dx)
        x = gs.means.detach().to(torch.float32)
        cell = torch.floor(x / dx).to(torch.int64)
        _, inverse, counts = torch.unique(cell, dim=0, return_inverse=True, return_counts=True)
        volume = dx**3 / counts[inverse].to(torch.float32)
        params = material_arrays(cfg.material, cfg.material_map, gs.labels.to(x.device), len(gs))
        v = torch.tensor(cfg.initial_velocity, dtype=torch.float32, device=x.device).expand_as(x)
        return Particles(x=x, v=v, mass=params.pop("density") * volume, volume=volume, interior=gs.interior, **params)


def _by_label(default: MaterialConfig, table, labels, n, field):
    out = torch.full(
        (n,),
        float(getattr(default, field)) if field != "model" else MATERIAL_IDS[default.model],
        dtype=torch.float32 if field != "model" else torch.int32,
        device=labels.device,
    )
    for entry in table:
        value = getattr(entry, field)
        if value is None:
            continue
        if field == "model":
            if value not in MATERIAL_IDS:
                raise SimulationError(
                    f"material_map label {entry.label}: model '{value}' is unknown; use one of {', '.join(MATERIALS)}"
                )
            value = MATERIAL_IDS[value]
        out[labels == entry.label] = value
    return out


def material_arrays(default: MaterialConfig, table, labels, n) -> dict:
    """Per-particle material parameters from a default and a label → parameters table."""
    fields = ("E", "nu", "density", "yield_stress", "hardening", "sigma_R", "friction_angle")
    out = {f: _by_label(default, table, labels, n, f) for f in fields}
    out["material"] = _by_label(default, table, labels, n, "model")
    return out
