"""Fit physical parameters to a video by gradient descent through simulation and splatting.

`fit_youngs_modulus` renders a target video of a scene with a known Young's modulus, starts from a
wrong guess and recovers E by Adam on log E with an image loss (mean squared error over every
frame), each gradient coming through the rasterizer (gsplat on CUDA, the torch rasterizer on the
CPU), the Gaussians' covariances F Σ⁰ Fᵀ and the differentiable frames of `FractureSim`. The
built-in `sagging_beam` problem: a beam on two supports sagging and ringing under gravity, whose
deflection and ring period both depend on E.
"""

from __future__ import annotations

import copy
import math
import time
from dataclasses import dataclass, field
from typing import Optional

import torch

from . import assets
from .config import CameraConfig, CuboidBoundary, SceneConfig
from .module import FractureSim
from .render.camera import from_config
from .render.gaussians import sh_colors
from .render.splat import render

NOISE = 1e-5  # relative loss change below which two evaluations count as equal (float32 atomics' order)


@dataclass
class FitResult:
    E_true: float
    E_start: float
    E: list = field(default_factory=list)  # E after each step [Pa]
    loss: list = field(default_factory=list)  # image loss before each step
    seconds: float = 0.0
    target: Optional[torch.Tensor] = None  # [T, H, W, 3] the target video
    fitted: Optional[torch.Tensor] = None  # [T, H, W, 3] the video with the fitted E

    @property
    def relative_error(self) -> float:
        return abs(self.E[-1] - self.E_true) / self.E_true


def sagging_beam(particles: int = 1500, frames: int = 12, dx: float = 1.0 / 32, density: float = 300.0) -> SceneConfig:
    """The beam scene on two end supports under gravity, no fracture, a side camera."""
    cfg = SceneConfig(
        name="sagging_beam", scene="beam", particles=particles, frames=frames, frame_dt=0.01, variants=["baseline"]
    )
    s = cfg.sim
    s.variant, s.dx, s.grid_shape, s.gravity = "baseline", dx, (round(1 / dx),) * 3, (0.0, 0.0, -9.8)
    s.adaptive_dt, s.cfl, s.dt = True, 0.4, 2e-3
    s.boundaries = [
        CuboidBoundary(lower=(0.19, 0.43, 0.25), upper=(0.25, 0.57, 0.3)),
        CuboidBoundary(lower=(0.75, 0.43, 0.25), upper=(0.81, 0.57, 0.3)),
    ]
    cfg.material.density = density
    cfg.render.width, cfg.render.height = 96, 48
    cfg.render.camera = CameraConfig(eye=(0.5, -0.55, 0.33), target=(0.5, 0.5, 0.31), fov_deg=36.0)
    return cfg


def render_video(cfg: SceneConfig, gs, out: dict, device: str) -> torch.Tensor:  # -> [T, H, W, 3]
    """Every frame of a FractureSim output, rendered from the config's camera (differentiable)."""
    cam = from_config(cfg.render.camera, cfg.render.width, cfg.render.height).to(device)
    sh, opac = gs.sh.to(device), gs.opacities.to(device)
    keep = ~gs.interior.to(device)
    frames = []
    for t in range(out["means"].shape[0]):
        means, covs = out["means"][t], out["covars"][t]
        colors = sh_colors(sh, means, cam.campos.to(means), out["rotations"][t])
        frames.append(
            render(means[keep], covs[keep], colors[keep], opac[keep], cam, background=cfg.render.background).image
        )
    return torch.stack(frames)


def fit_youngs_modulus(
    cfg: SceneConfig, E_true: float, E_start: float, steps: int = 20, lr: float = 0.15, device: str = "cpu", log=print
) -> FitResult:
    """Recover E from a video rendered with E_true, starting at E_start (Adam on log E)."""
    gs = assets.build(cfg.scene, n=cfg.particles).to(device)
    cfg = copy.deepcopy(cfg)
    cfg.material.E = float(E_true)
    # the topology (none for a sagging beam) and Δt plan follow from the target run
    truth = FractureSim(cfg, device=device, differentiable=True)
    with torch.no_grad():
        target = render_video(
            cfg,
            gs,
            truth(
                gs.means, gs.opacities, gs.sh, quats=gs.quats, scales=gs.scales, interior=gs.interior, labels=gs.labels
            ),
            device,
        )
    model = FractureSim(cfg, device=device, differentiable=True)
    log_E = torch.tensor(math.log(E_start), dtype=torch.float64, device=device, requires_grad=True)
    opt = torch.optim.Adam([log_E], lr=lr)
    res = FitResult(E_true=float(E_true), E_start=float(E_start), target=target.detach().cpu())
    best = (math.inf, float(log_E.detach()))
    t0 = time.perf_counter()
    for step in range(steps):
        opt.zero_grad()
        out = model(
            gs.means,
            gs.opacities,
            gs.sh,
            quats=gs.quats,
            scales=gs.scales,
            interior=gs.interior,
            labels=gs.labels,
            E=torch.exp(log_E).float(),
        )
        video = render_video(cfg, gs, out, device)
        loss = ((video - target) ** 2).mean()
        loss.backward()
        value, E_now = float(loss.detach()), float(torch.exp(log_E.detach()))
        res.loss.append(value)
        res.E.append(E_now)
        log(
            f"step {step + 1:3d}/{steps}: E = {E_now:.4g} Pa (true {E_true:.4g}, error "
            f"{100 * abs(E_now - E_true) / E_true:.1f} %), loss {value:.3e}"
        )
        # overshot: back to the best E with half the step (and Adam's momentum reset). A loss within
        # NOISE of the best is no overshoot: on a GPU the same E gives losses that differ in the last
        # digits (atomics sum in varying order), and treating that as one froze the fit at the best E.
        if value > best[0] * (1.0 + NOISE):
            with torch.no_grad():
                log_E.fill_(best[1])
            lr *= 0.5
            opt = torch.optim.Adam([log_E], lr=lr)
        else:
            if value < best[0]:
                best = (value, float(log_E.detach()))
            opt.step()
    res.E.append(math.exp(best[1]))  # the answer: the E of the lowest loss seen
    res.loss.append(best[0])
    res.seconds = time.perf_counter() - t0
    with torch.no_grad():
        out = model(
            gs.means,
            gs.opacities,
            gs.sh,
            quats=gs.quats,
            scales=gs.scales,
            interior=gs.interior,
            labels=gs.labels,
            E=torch.tensor(res.E[-1], dtype=torch.float32, device=device),
        )
        res.fitted = render_video(cfg, gs, out, device).cpu()
    return res
