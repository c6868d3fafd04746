"""`FractureSim`: the simulation as a torch.nn.Module for reconstruction pipelines.

    sim = fgs.FractureSim("bread", variant="full", device="cuda:0")
    out = sim(means, opacities, sh, quats=quats, scales=scales)     # Gaussians in
    out["means"][t], out["covars"][t], out["fragment"][t]             # per-frame tensors out

By default the forward pass runs the plain (fast, forward-only) solver and returns plain tensors on
the simulation device, ready for gsplat's `rasterization`. `FractureSim(..., differentiable=True)`
returns tensors with gradients to the Gaussians and to E, ν, density and initial velocity.
"""

from __future__ import annotations

import copy
import os
from typing import Iterator, Optional, Union

import torch

from .config import MaterialMapEntry, SceneConfig
from .errors import ArgumentError, ConfigError, SimulationError
from .io import GaussianSet
from .io.gaussian_set import as_tensor, check_gaussians
from .linalg import eigh_chunked
from .pipeline import FrameOutput, check_config, make_simulator, simulate
from .variants import VARIANT_NAMES

FORWARD = "FractureSim.forward"


def _quats_from_rotations(R: torch.Tensor) -> torch.Tensor:  # [N,3,3] -> [N,4] wxyz
    """Quaternion of a rotation matrix (Shepperd's method, branch-free via the largest diagonal)."""
    m = R
    t = torch.stack(
        [
            1 + m[:, 0, 0] + m[:, 1, 1] + m[:, 2, 2],
            1 + m[:, 0, 0] - m[:, 1, 1] - m[:, 2, 2],
            1 - m[:, 0, 0] + m[:, 1, 1] - m[:, 2, 2],
            1 - m[:, 0, 0] - m[:, 1, 1] + m[:, 2, 2],
        ],
        1,
    )
    k = t.argmax(1)
    s = torch.sqrt(t.gather(1, k[:, None]).clamp_min(1e-12))[:, 0] * 2
    q = torch.stack(
        [
            torch.stack(
                [s / 4, (m[:, 2, 1] - m[:, 1, 2]) / s, (m[:, 0, 2] - m[:, 2, 0]) / s, (m[:, 1, 0] - m[:, 0, 1]) / s], 1
            ),
            torch.stack(
                [(m[:, 2, 1] - m[:, 1, 2]) / s, s / 4, (m[:, 0, 1] + m[:, 1, 0]) / s, (m[:, 0, 2] + m[:, 2, 0]) / s], 1
            ),
            torch.stack(
                [(m[:, 0, 2] - m[:, 2, 0]) / s, (m[:, 0, 1] + m[:, 1, 0]) / s, s / 4, (m[:, 1, 2] + m[:, 2, 1]) / s], 1
            ),
            torch.stack(
                [(m[:, 1, 0] - m[:, 0, 1]) / s, (m[:, 0, 2] + m[:, 2, 0]) / s, (m[:, 1, 2] + m[:, 2, 1]) / s, s / 4], 1
            ),
        ],
        1,
    )
    return torch.nn.functional.normalize(q[torch.arange(len(k)), k], dim=1)


def gaussians_from_tensors(
    means, opacities, sh, quats=None, scales=None, covars=None, interior=None, labels=None, where: str = FORWARD
) -> GaussianSet:
    """A GaussianSet from raw tensors; covariances are factored into rotation and scales. Every argument is
    checked (`io.gaussian_set.check_gaussians`): one ArgumentError sentence naming it and the fix."""
    means = as_tensor(where, "means", means, "[N, 3]")
    opacities = as_tensor(where, "opacities", opacities, "[N]")
    if opacities.dim() == 2 and opacities.shape[1] == 1:  # [N, 1] as some trainers keep them
        opacities = opacities.reshape(-1)
    sh = as_tensor(where, "sh", sh, "[N, K, 3] or [N, 3]")
    if sh.dim() == 2:
        sh = sh[:, None, :]
    if covars is not None:
        if quats is not None or scales is not None:
            raise ArgumentError(
                f"{where}: covars and quats/scales were both given, and covars would replace them; pass either "
                "quats and scales, or covars."
            )
        quats, scales = _factor_covariances(where, means, covars)
    if quats is None or scales is None:
        missing = "quats" if quats is None else "scales"
        raise ArgumentError(
            f"{where}: {missing} is missing; pass quats [N, 4] and scales [N, 3], or covars [N, 3, 3], "
            "for every Gaussian."
        )
    arrays = check_gaussians(
        where,
        means=means,
        quats=quats,
        scales=scales,
        opacities=opacities,
        sh=sh,
        interior=interior,
        labels=labels,
    )
    return GaussianSet(**arrays)


def _factor_covariances(where: str, means, covars) -> tuple[torch.Tensor, torch.Tensor]:
    """(quats [N, 4], scales [N, 3]) of covariances [N, 3, 3] that are finite, symmetric and positive
    semi-definite (within float rounding)."""
    means = check_gaussians(where, means=means)["means"]
    cov = as_tensor(where, "covars", covars, "[N, 3, 3]")
    if cov.dim() != 3 or tuple(cov.shape) != (len(means), 3, 3):
        raise ArgumentError(
            f"{where}: covars has shape {list(cov.shape)}, not [N, 3, 3] with N = {len(means)} (the number of "
            "means); pass one 3×3 covariance per Gaussian."
        )
    if cov.is_complex() or cov.dtype == torch.bool:
        raise ArgumentError(f"{where}: covars has dtype {cov.dtype}; pass real numbers (float32).")
    c = cov.detach().double()
    if len(c) == 0:
        return means.new_zeros(0, 4), means.new_zeros(0, 3)
    evals, evecs = eigh_chunked(c) if bool(torch.isfinite(c).all()) else (None, None)
    scale = c.abs().amax((1, 2)).clamp_min(1e-300)
    bad = None
    if evals is None:
        bad = "NaN or infinite entries"
    elif bool(((c - c.transpose(1, 2)).abs().amax((1, 2)) > 1e-5 * scale).any()):
        bad = "entries that are not symmetric"
    elif bool((evals.amin(1) < -1e-6 * scale).any()):
        bad = "negative eigenvalues (not positive semi-definite)"
    if bad is not None:
        raise ArgumentError(
            f"{where}: covars has {bad}; pass covariances R S Sᵀ Rᵀ (symmetric, positive semi-definite, finite)."
        )
    evecs = evecs * torch.sign(torch.det(evecs))[:, None, None]  # proper rotation
    dtype = means.dtype
    return _quats_from_rotations(evecs).to(dtype), evals.clamp_min(1e-20).sqrt().to(dtype)


def _material_argument(name: str, value, n: int) -> torch.Tensor:
    """E, nu or density of the differentiable forward: a scalar or [N], finite, within the range the config
    allows (`io.config.validate`'s material rules, the one statement of those ranges)."""
    t = as_tensor(FORWARD, name, value, "a scalar or [N]")
    if t.is_complex() or t.dtype == torch.bool:
        raise ArgumentError(f"{FORWARD}: {name} has dtype {t.dtype}; pass real numbers.")
    if not t.is_floating_point():
        t = t.to(torch.float32)
    if t.dim() > 1 or (t.dim() == 1 and len(t) != n):
        raise ArgumentError(
            f"{FORWARD}: {name} has shape {list(t.shape)}, not a scalar or [N] with N = {n} (the number of means); "
            "pass one value, or one per Gaussian."
        )
    if t.numel():
        d = t.detach()
        for v in [float("nan")] if bool(torch.isnan(d).any()) else torch.stack([d.min(), d.max()]).tolist():
            problem = _material_problem(name, v)
            if problem is not None:
                shown = float(f"{v:{'.15g' if d.dtype == torch.float64 else '.7g'}}")  # 0.7, not 0.699999988
                raise ArgumentError(_material_problem(name, shown) or problem)
    return t


def _material_problem(name: str, value: float) -> Optional[str]:
    """The config's sentence for material.<name> = value (`io.config.validate`), as the argument `name`."""
    from .io.config.validate import _check_material, _Checker

    try:
        _check_material(_Checker(FORWARD), "material", MaterialMapEntry(**{name: value}))
    except ConfigError as exc:
        return str(exc).replace(f"material.{name}", name)
    return None


def _velocity_argument(value, n: int) -> torch.Tensor:
    """The initial velocity: [3] or [N, 3] finite values [m/s]."""
    t = as_tensor(FORWARD, "velocity", value, "[3] or [N, 3]")
    if t.is_complex() or t.dtype == torch.bool:
        raise ArgumentError(f"{FORWARD}: velocity has dtype {t.dtype}; pass real numbers in m/s.")
    if tuple(t.shape) not in ((3,), (n, 3)):
        raise ArgumentError(
            f"{FORWARD}: velocity has shape {list(t.shape)}, not [3] or [N, 3] with N = {n} (the number of means); "
            "pass one velocity for all Gaussians or one per Gaussian (m/s)."
        )
    if not bool(torch.isfinite(t.detach()).all()):
        raise ArgumentError(f"{FORWARD}: velocity has NaN or infinite entries; pass finite velocities (m/s).")
    from .io.config.validate import MAX_SPEED

    fastest = float(t.detach().double().norm(dim=-1).max()) if t.numel() else 0.0
    if fastest > MAX_SPEED:
        raise ArgumentError(
            f"{FORWARD}: velocity reaches {fastest:.3g} m/s, over {MAX_SPEED:g} m/s; pass velocities in m/s (the "
            "substep shrinks with the speed: Δt ≤ CFL·Δx / |v|)."
        )
    return t


def _check_topology(topology) -> None:
    """`topology`: None, a `sim.topology.Topology` or a non-empty list of them (a run's history)."""
    from .sim.topology import Topology

    items = topology if isinstance(topology, (list, tuple)) else [topology]
    if topology is None or (items and all(isinstance(t, Topology) for t in items)):
        return
    raise ArgumentError(
        f"FractureSim: topology must be a Topology or a list of them, got {type(topology).__name__}; pass "
        "fracture_gs.sim.topology.load_history('topology.npz'), or None to find it by a plain run."
    )


class FractureSim(torch.nn.Module):
    """Gaussians in, per-frame deformed Gaussians and fragment ids out (one configured variant).

    With `differentiable=True` the outputs carry gradients back to the Gaussians' means, quats and
    scales and to the physical parameters passed to `forward` (E, nu, density, velocity): the
    simulation runs as `fracture_gs.sim.diff.DiffSimulator` frames (Warp adjoints, one checkpoint
    per frame). The fracture topology is found once by a plain run (or given as `topology`) and held
    fixed: gradients flow through each fragment's dynamics on both sides of a latch."""

    def __init__(
        self,
        cfg: Union[SceneConfig, str],
        variant: Optional[str] = None,
        device: Optional[str] = None,
        topology=None,
        diagnostics: bool = True,
        differentiable: bool = False,
    ):
        super().__init__()
        if isinstance(cfg, (str, os.PathLike)):
            from .io.config import load_config

            cfg = load_config(cfg)
        if not isinstance(cfg, SceneConfig):
            raise ArgumentError(
                f"FractureSim: cfg must be a SceneConfig, got {type(cfg).__name__}; pass a config (fracture_gs.io."
                "load_config) or the name or path of one, e.g. FractureSim('bread')."
            )
        self.cfg = copy.deepcopy(cfg)
        if variant is None:
            variant = self.cfg.variants[-1] if self.cfg.variants else self.cfg.sim.variant
        self.variant = variant
        if self.variant not in VARIANT_NAMES:
            raise ArgumentError(
                f"FractureSim: variant {self.variant!r} is unknown; use one of {', '.join(VARIANT_NAMES)}."
            )
        if device is not None:
            from .io.ply import as_device

            as_device("FractureSim", device)
        self.device_name = device
        _check_topology(topology)
        for name, flag in (("diagnostics", diagnostics), ("differentiable", differentiable)):
            if not isinstance(flag, bool):
                raise ArgumentError(
                    f"FractureSim: {name} must be True or False, not {flag!r:.40}; pass {name}=True or {name}=False."
                )
        self.topology = topology
        self.diagnostics = diagnostics
        self.differentiable = differentiable
        self.last_simulator = None

    def frames(self, gs: GaussianSet) -> Iterator[FrameOutput]:
        """Stream FrameOutputs (frame 0 = input state) without stacking them."""
        if not isinstance(gs, GaussianSet):
            raise ArgumentError(
                f"FractureSim.frames: gs is a {type(gs).__name__}, not a GaussianSet; call the module with tensors "
                "(sim(means, opacities, sh, quats=..., scales=...)) or build a fracture_gs.io.GaussianSet."
            )
        device = self._device(gs)
        self._check_cfg()
        sim = make_simulator(self.cfg, gs, self.variant, device, topology=self.topology)
        self.last_simulator = sim
        cov0 = gs.covariances().to(device, torch.float32)
        yield from simulate(sim, cov0, self.cfg.frames, self.cfg.frame_dt, diagnostics=self.diagnostics)

    def _check_cfg(self) -> None:
        """The config as it is now (a user may edit `self.cfg` after construction): the loader's checks."""
        check_config(self.cfg, f"FractureSim cfg ({self.cfg.name})")

    def _device(self, gs: GaussianSet) -> str:
        return self.device_name or (str(gs.means.device) if gs.means.is_cuda else "cpu")

    def forward(
        self,
        means: torch.Tensor,  # [N, 3]
        opacities: Optional[torch.Tensor] = None,  # [N] (required: None is refused with the fix)
        sh: Optional[torch.Tensor] = None,  # [N, K, 3] (or [N, 3] colours as degree-0 SH); required
        quats: Optional[torch.Tensor] = None,  # [N, 4] wxyz
        scales: Optional[torch.Tensor] = None,  # [N, 3]
        covars: Optional[torch.Tensor] = None,  # [N, 3, 3] instead of quats/scales
        interior: Optional[torch.Tensor] = None,  # [N] bool: fill particles
        labels: Optional[torch.Tensor] = None,  # [N] int material labels
        E: Optional[torch.Tensor] = None,  # scalar or [N] Young's modulus [Pa] (differentiable mode)
        nu: Optional[torch.Tensor] = None,  # scalar or [N] Poisson ratio
        density: Optional[torch.Tensor] = None,  # scalar or [N] [kg/m³]
        velocity: Optional[torch.Tensor] = None,  # [3] or [N, 3] initial velocity [m/s]
    ) -> dict:
        """Runs cfg.frames frames; returns {"means": [T+1,N,3], "covars": [T+1,N,3,3],
        "rotations": [T+1,N,3,3], "fragment": [T+1,N], "time": [T+1], "metrics": list[dict]}."""
        # labels without cfg.material_map are accepted and change nothing: they travel with a scene's Gaussians
        # (`gs.labels`), and passing a scene through whole is the documented use (round four had refused them)
        if isinstance(means, GaussianSet):  # sim(gs) was "missing 2 required positional arguments"
            raise ArgumentError(
                "FractureSim.forward: got a GaussianSet, but the module takes its tensors; call sim(gs.means, "
                "gs.opacities, gs.sh, quats=gs.quats, scales=gs.scales), or stream it with sim.frames(gs)."
            )
        for name, value in (("opacities", opacities), ("sh", sh)):
            if value is None:
                raise ArgumentError(
                    f"FractureSim.forward: {name} is missing; pass means, opacities and sh, e.g. "
                    "sim(means, opacities, sh, quats=quats, scales=scales)."
                )
        gs = gaussians_from_tensors(means, opacities, sh, quats, scales, covars, interior, labels)
        if self.differentiable:
            from .differentiable import differentiable_forward

            n = len(gs)
            E, nu, density = (
                None if v is None else _material_argument(k, v, n)
                for k, v in (("E", E), ("nu", nu), ("density", density))
            )
            velocity = None if velocity is None else _velocity_argument(velocity, n)
            self._check_cfg()
            return differentiable_forward(self, gs, E, nu, density, velocity)
        given = [k for k, t in (("E", E), ("nu", nu), ("density", density), ("velocity", velocity)) if t is not None]
        if given:
            raise SimulationError(
                f"{FORWARD}: {', '.join(given)} would be ignored: E, nu, density and velocity are inputs of the "
                "differentiable mode; create FractureSim(..., differentiable=True) or set them in the config."
            )
        with torch.no_grad():
            outs = list(self.frames(gs))
        return {
            "means": torch.stack([o.means for o in outs]),
            "covars": torch.stack([o.covars for o in outs]),
            "rotations": torch.stack([o.rotations for o in outs]),
            "fragment": torch.stack([o.fragment for o in outs]),
            "time": torch.tensor([o.time for o in outs]),
            "metrics": [o.metrics for o in outs],
        }
