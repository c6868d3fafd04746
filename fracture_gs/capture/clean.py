"""Clean a captured scene before it is simulated: broken Gaussians, floaters and far outliers.

Trainers leave three kinds of debris: Gaussians with non-finite or degenerate parameters, faint
"floaters" (opacity near zero) that float in the air in front of the cameras, and isolated
Gaussians far from everything else. The first two go by value; outliers go by the statistical
criterion of point-cloud tools: a Gaussian whose mean distance to its k nearest neighbours exceeds
the mean of that distance over the scene by more than `std` standard deviations.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from ..io.gaussian_set import GaussianSet


@dataclass
class CleanReport:
    """How many Gaussians each criterion removed."""

    total: int
    broken: int = 0
    faint: int = 0
    outliers: int = 0

    @property
    def kept(self) -> int:
        return self.total - self.broken - self.faint - self.outliers

    def line(self) -> str:
        return (
            f"kept {self.kept} of {self.total} Gaussians (removed {self.broken} broken, {self.faint} faint floaters, "
            f"{self.outliers} far outliers)"
        )


def broken_mask(gs: GaussianSet) -> torch.Tensor:  # [N] bool
    """Gaussians that cannot be simulated or drawn: non-finite values, non-positive scales, zero quaternions."""
    ok = torch.isfinite(gs.means).all(1) & torch.isfinite(gs.quats).all(1) & torch.isfinite(gs.scales).all(1)
    ok &= torch.isfinite(gs.opacities) & torch.isfinite(gs.sh).flatten(1).all(1)
    ok &= (gs.scales > 0).all(1) & (torch.linalg.vector_norm(gs.quats, dim=1) > 0)
    return ~ok


def outlier_mask(points: torch.Tensor, neighbours: int, std: float) -> torch.Tensor:  # [N, 3] -> [N] bool
    """Statistical outliers: mean distance to the k nearest neighbours above mean + std·σ (k-d tree)."""
    n = len(points)
    if neighbours <= 0 or n <= neighbours + 1:
        return torch.zeros(n, dtype=torch.bool)
    from scipy.spatial import cKDTree

    p = points.detach().to("cpu", torch.float64).numpy()
    dist, _ = cKDTree(p).query(p, k=neighbours + 1)
    mean = torch.from_numpy(dist[:, 1:].mean(1))
    return mean > mean.mean() + std * mean.std()


def clean(gs: GaussianSet, min_opacity: float, neighbours: int, std: float) -> tuple[torch.Tensor, CleanReport]:
    """(keep [N] bool, report): broken Gaussians, then floaters (opacity < min_opacity), then outliers
    among the rest."""
    report = CleanReport(total=len(gs))
    broken = broken_mask(gs)
    report.broken = int(broken.sum())
    faint = ~broken & (gs.opacities < min_opacity)
    report.faint = int(faint.sum())
    keep = ~broken & ~faint
    idx = torch.nonzero(keep).squeeze(1)
    out = outlier_mask(gs.means[idx], neighbours, std)
    keep[idx[out]] = False
    report.outliers = int(out.sum())
    return keep, report
