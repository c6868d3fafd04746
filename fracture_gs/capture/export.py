"""Simulated frames as splat files (`render-sim --export-ply N [--export-format F]`), in the scene's own frame.

Each exported Gaussian is a drawn one of the frame: mean x_p, covariance Σ = F Σ⁰ Fᵀ split back
into a rotation and scales, SH coefficients rotated by R(F) (so a viewer that knows nothing of the
simulation shows the same colours), opacity unchanged; interior fill particles stay out unless a
fracture exposed them. The static background is appended, and the inverse of the capture fit takes
everything back to the trainer's coordinates, so the PLY drops into any splat viewer beside the
original. `--export-format` picks the file format (3DGS PLY by default; compressed PLY, .splat or .spz
through `io.formats.write_gaussians`, which says what each keeps).
"""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import torch

from ..io.formats import write_gaussians
from ..io.gaussian_set import GaussianSet
from .transform import SceneTransform, gaussians_from_covariances, rotate_sh


def frame_gaussians(
    rest: GaussianSet, means: torch.Tensor, covars: torch.Tensor, rotations: torch.Tensor, drawn: torch.Tensor
) -> GaussianSet:
    """The drawn Gaussians of one frame in the simulation frame. rest: the simulated set at t = 0
    ([N]); means [N, 3], covars [N, 3, 3], rotations [N, 3, 3] R(F); drawn [N] bool."""
    idx = torch.nonzero(drawn.to(means.device)).squeeze(1)
    quats, scales = gaussians_from_covariances(covars[idx].to(torch.float64))
    rest = rest.to(means.device)
    return GaussianSet(
        means=means[idx].float(),
        quats=quats.float(),
        scales=scales.float(),
        opacities=rest.opacities[idx].float(),
        sh=rotate_sh(rest.sh[idx].float(), rotations[idx]),
        labels=rest.labels[idx],
        extra={k: v[idx] for k, v in rest.extra.items()},
    )


def export_ply(
    path: Path,
    gs: GaussianSet,
    background: Optional[GaussianSet],
    to_scene: Optional[SceneTransform],
    fmt: str = "ply",
) -> Path:
    """Write gs (+ background) as a splat file in `fmt` (`io.formats.FORMATS`; default a 3DGS PLY), mapped
    back to the scene's frame when `to_scene` is given."""
    if background is not None and len(background):
        bg = background.to(gs.device)
        gs = GaussianSet(
            means=torch.cat([gs.means, bg.means.float()]),
            quats=torch.cat([gs.quats, bg.quats.float()]),
            scales=torch.cat([gs.scales, bg.scales.float()]),
            opacities=torch.cat([gs.opacities, bg.opacities.float()]),
            sh=torch.cat([gs.sh, _pad_sh(bg.sh.float(), gs.sh.shape[1])]),
        )
    if to_scene is not None:
        gs = to_scene.gaussians(gs)
    path.parent.mkdir(parents=True, exist_ok=True)
    return write_gaussians(gs.to("cpu"), path, fmt)


def _pad_sh(sh: torch.Tensor, k: int) -> torch.Tensor:
    if sh.shape[1] >= k:
        return sh[:, :k]
    return torch.cat([sh, torch.zeros(sh.shape[0], k - sh.shape[1], 3, dtype=sh.dtype, device=sh.device)], 1)
