"""A small synthetic run folder for the viewer's tests: two coloured blocks written through the same writer as
render-sim (`viewer.record`), without simulating anything.

A red block (x < 0.5) and a blue block (x > 0.5), each a lattice of Gaussians, the band the layer at the cut. In
`full` the blocks fracture at frame 1 (fragments 0 and 1) and drift apart along x; in `baseline` they stay
whole and sag downward. The camera looks at the blocks' centre from −y.
"""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import numpy as np
import torch

from fracture_gs.config import CameraConfig, SceneConfig
from fracture_gs.io import GaussianSet
from fracture_gs.sh import SH_C0
from fracture_gs.viewer.record import FrameRecorder, start_record

CENTRE = (0.5, 0.5, 0.3)


def blocks(per_axis: int = 12) -> GaussianSet:
    """Two blocks side by side along x, red then blue, Gaussians of σ = 12 mm on a 20 mm lattice."""
    g = (np.arange(per_axis) + 0.5) / per_axis * 0.24
    cells = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3)
    left = cells + np.array([0.5 - 0.25, 0.5 - 0.12, 0.3 - 0.12])
    right = cells + np.array([0.5 + 0.01, 0.5 - 0.12, 0.3 - 0.12])
    means = torch.tensor(np.concatenate([left, right]), dtype=torch.float32)
    n = len(means)
    rgb = torch.zeros(n, 3)
    rgb[: n // 2] = torch.tensor([0.85, 0.15, 0.1])
    rgb[n // 2 :] = torch.tensor([0.1, 0.2, 0.85])
    return GaussianSet(
        means=means,
        quats=torch.tensor([[1.0, 0, 0, 0]]).repeat(n, 1),
        scales=torch.full((n, 3), 0.012),
        opacities=torch.full((n,), 0.95),
        sh=((rgb - 0.5) / SH_C0)[:, None, :],
    )


def config(frames: int) -> SceneConfig:
    cfg = SceneConfig(name="blocks", frames=frames, frame_dt=0.02)
    cfg.render.camera = CameraConfig(eye=(0.5, -0.9, 0.45), target=CENTRE, up=(0.0, 0.0, 1.0), fov_deg=40.0)
    return cfg


def frame_output(gs: GaussianSet, variant: str, k: int, dt: float) -> SimpleNamespace:
    """Frame k of a variant: `full` split in two fragments from frame 1 on, moving apart; `baseline` sagging."""
    means = gs.means.clone()
    n = len(means)
    left = means[:, 0] < 0.5
    fragment = torch.full((n,), -1, dtype=torch.int32)
    band = torch.zeros(n, dtype=torch.int32)
    if variant == "full" and k >= 1:
        fragment = (~left).to(torch.int32)
        band = ((means[:, 0] - 0.5).abs() < 0.03).to(torch.int32)
        means[left, 0] -= 0.03 * k
        means[~left, 0] += 0.03 * k
    else:
        means[:, 2] -= 0.01 * k * (1 - (means[:, 0] - 0.5).abs() * 4).clamp(min=0)
    covars = gs.covariances()
    return SimpleNamespace(frame=k, time=k * dt, means=means, covars=covars, fragment=fragment, band=band)


def make_run(
    out: Path, frames: int = 6, variants=("baseline", "full"), per_axis: int = 12, background: bool = False
) -> Path:
    """Write a view record of the two blocks into `out` (frames 0 … frames of each variant); returns `out`."""
    gs = blocks(per_axis)
    cfg = config(frames)
    bg = None
    if background:  # a floor of grey Gaussians under the blocks
        g = np.linspace(0.1, 0.9, 20)
        xy = np.stack(np.meshgrid(g, g, indexing="ij"), -1).reshape(-1, 2)
        floor = torch.tensor(np.c_[xy, np.full(len(xy), 0.16)], dtype=torch.float32)
        m = len(floor)
        bg = GaussianSet(
            means=floor,
            quats=torch.tensor([[1.0, 0, 0, 0]]).repeat(m, 1),
            scales=torch.tensor([[0.03, 0.03, 0.004]]).repeat(m, 1),
            opacities=torch.full((m,), 0.9),
            sh=torch.zeros(m, 1, 3),
        )
    folder = start_record(out, cfg, gs, bg, variants)
    rgb = (gs.sh[:, 0, :] * SH_C0 + 0.5).clamp(0, 1)
    drawn = torch.ones(len(gs), dtype=torch.bool)
    for v in variants:
        rec = FrameRecorder(folder, v)
        for k in range(frames + 1):
            rec.write(frame_output(gs, v, k, cfg.frame_dt), rgb, drawn)
        rec.close()
    return Path(out)
