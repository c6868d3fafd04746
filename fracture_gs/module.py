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
from typing import Iterator, Optional, Union

import torch

from .config import SceneConfig
from .errors import SimulationError
from .io import GaussianSet
from .linalg import eigh_chunked
from .pipeline import FrameOutput, make_simulator, simulate


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
    means, opacities, sh, quats=None, scales=None, covars=None, interior=None, labels=None
) -> GaussianSet:
    """A GaussianSet from raw tensors; covariances are factored into rotation and scales."""
    if covars is not None:
        evals, evecs = eigh_chunked(covars.double())
        evecs = evecs * torch.sign(torch.det(evecs))[:, None, None]  # proper rotation
        quats = _quats_from_rotations(evecs).to(means.dtype)
        scales = evals.clamp_min(1e-20).sqrt().to(means.dtype)
    if quats is None or scales is None:
        raise SimulationError("FractureSim needs either quats and scales, or covars, for every Gaussian")
    if sh.ndim == 2:
        sh = sh[:, None, :]
    return GaussianSet(
        means=means,
        quats=quats,
        scales=scales,
        opacities=opacities.reshape(-1),
        sh=sh,
        interior=interior,
        labels=labels,
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
        if isinstance(cfg, str):
            from .io.config import load_config

            cfg = load_config(cfg)
        self.cfg = copy.deepcopy(cfg)
        self.variant = variant or (self.cfg.variants[-1] if self.cfg.variants else self.cfg.sim.variant)
        self.device_name = device
        self.topology = topology
        self.diagnostics = diagnostics
        self.differentiable = differentiable
        self.last_simulator = None

    def frames(self, gs: GaussianSet) -> Iterator[FrameOutput]:
        """Stream FrameOutputs (frame 0 = input state) without stacking them."""
        device = self._device(gs)
        sim = make_simulator(self.cfg, gs, self.variant, device, topology=self.topology)
        self.last_simulator = sim
        cov0 = gs.covariances().to(device, torch.float32)
        yield from simulate(sim, cov0, self.cfg.frames, self.cfg.frame_dt, diagnostics=self.diagnostics)

    def _device(self, gs: GaussianSet) -> str:
        return self.device_name or (str(gs.means.device) if gs.means.is_cuda else "cpu")

    def forward(
        self,
        means: torch.Tensor,  # [N, 3]
        opacities: torch.Tensor,  # [N]
        sh: torch.Tensor,  # [N, K, 3] (or [N, 3] colours as degree-0 SH)
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
        gs = gaussians_from_tensors(means, opacities, sh, quats, scales, covars, interior, labels)
        if self.differentiable:
            from .differentiable import differentiable_forward

            return differentiable_forward(self, gs, E, nu, density, velocity)
        if any(t is not None for t in (E, nu, density, velocity)):
            raise SimulationError(
                "E, nu, density and velocity are inputs of the differentiable mode; "
                "create FractureSim(..., differentiable=True) or set them in the config"
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
