"""Trainer-like 3DGS scenes built in the test: what the reference trainer writes for a captured object.

COLMAP-scale coordinates far from the origin, y pointing down, SH degree 3, flat surface Gaussians
with many faint ones (median opacity ≈ 0.06) between opaque ones, a few floaters in the air and
far outliers, and optionally a cameras.json of views around the object.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import torch

from fracture_gs.capture.transform import quat_from_matrix
from fracture_gs.io.gaussian_set import GaussianSet
from fracture_gs.io.ply import save_ply

SCENE_SCALE = 40.0  # scene units per metre of the real object
SCENE_OFFSET = (120.0, -40.0, 300.0)  # far from the origin
SEMI_AXES = (0.25, 0.15, 0.12)  # the object's semi-axes in metres (x long, y up/down, z depth)


def _frames(normals: torch.Tensor) -> torch.Tensor:  # [N, 3] unit -> [N, 3, 3] columns t1, t2, n
    a = torch.where(normals[:, :1].abs() < 0.9, torch.tensor([[1.0, 0, 0]]), torch.tensor([[0, 1.0, 0]]))
    t1 = torch.nn.functional.normalize(torch.linalg.cross(a, normals), dim=1)
    t2 = torch.linalg.cross(normals, t1)
    return torch.stack([t1, t2, normals], 2)


def object_surface(n: int, seed: int = 0, open_shell: bool = False) -> tuple[GaussianSet, float]:
    """Surface Gaussians of an ellipsoid (x up = −y in the scene), in metres around the origin;
    `open_shell` keeps only its upper half (a bowl). Returns (gaussians, true volume m³)."""
    g = torch.Generator().manual_seed(seed)
    d = torch.nn.functional.normalize(torch.randn(3 * n, 3, generator=g), dim=1)
    a = torch.tensor(SEMI_AXES)
    p = d * a
    if open_shell:
        p = p[p[:, 1] < 0]  # y down: the upper half (y < 0) stays, the bowl opens downwards
    p = p[:n]
    normals = torch.nn.functional.normalize(p / a**2, dim=1)
    area = 4 * math.pi * (((a[0] * a[1]) ** 1.6 + (a[0] * a[2]) ** 1.6 + (a[1] * a[2]) ** 1.6) / 3) ** (1 / 1.6)
    m = len(p)
    spacing = float(area * (0.5 if open_shell else 1.0) / m) ** 0.5  # neighbours overlap, as a trained surface
    scales = torch.stack([torch.full((m,), spacing), torch.full((m,), spacing), torch.full((m,), spacing / 8)], 1)
    scales = scales * (0.7 + 0.6 * torch.rand(m, 1, generator=g))
    opac = torch.where(
        torch.rand(m, generator=g) < 0.35,
        0.5 + 0.45 * torch.rand(m, generator=g),
        0.015 + 0.09 * torch.rand(m, generator=g),
    )
    sh = torch.zeros(m, 16, 3)
    sh[:, 0] = torch.tensor([0.9, 0.4, 0.1]) + 0.2 * torch.randn(m, 3, generator=g)
    sh[:, 1:] = 0.05 * torch.randn(m, 15, 3, generator=g)
    gs = GaussianSet(means=p, quats=quat_from_matrix(_frames(normals)).float(), scales=scales, opacities=opac, sh=sh)
    return gs, 4 / 3 * math.pi * float(a.prod())


def to_scene(gs: GaussianSet) -> GaussianSet:
    """Metres around the origin (y down already) → scene units far away."""
    return gs.replace(means=gs.means * SCENE_SCALE + torch.tensor(SCENE_OFFSET), scales=gs.scales * SCENE_SCALE)


def debris(n_floaters: int, n_far: int, seed: int = 1) -> GaussianSet:
    """Faint floaters in the air around the object and a few opaque Gaussians far away (scene units)."""
    g = torch.Generator().manual_seed(seed)
    fl = (torch.rand(n_floaters, 3, generator=g) - 0.5) * 2.0 * SCENE_SCALE * 0.6
    far = torch.randn(n_far, 3, generator=g) * 40 * SCENE_SCALE
    p = torch.cat([fl, far]) + torch.tensor(SCENE_OFFSET)
    m = len(p)
    opac = torch.cat([torch.full((n_floaters,), 0.004), torch.full((n_far,), 0.8)])
    quats = torch.zeros(m, 4)
    quats[:, 0] = 1
    return GaussianSet(means=p, quats=quats, scales=torch.full((m, 3), 0.2), opacities=opac, sh=torch.zeros(m, 16, 3))


def concat(a: GaussianSet, b: GaussianSet) -> GaussianSet:
    return GaussianSet(
        *(torch.cat([getattr(a, k), getattr(b, k)]) for k in ("means", "quats", "scales", "opacities", "sh"))
    )


def write_trainer_ply(
    folder: Path,
    n: int = 4000,
    seed: int = 0,
    open_shell: bool = False,
    floaters: int = 40,
    far: int = 5,
    cameras: bool = False,
) -> tuple[Path, float]:
    """A trainer-like model folder (`point_cloud/iteration_30000/point_cloud.ply`, and `cameras.json`
    when asked); returns (PLY path, true object volume in m³)."""
    obj, volume = object_surface(n, seed, open_shell)
    gs = concat(to_scene(obj), debris(floaters, far, seed + 1))
    ply = folder / "point_cloud" / "iteration_30000" / "point_cloud.ply"
    ply.parent.mkdir(parents=True, exist_ok=True)
    save_ply(gs, ply)
    if cameras:
        write_cameras(folder / "cameras.json")
    return ply, volume


def write_cameras(path: Path, views: int = 8) -> None:
    """Views on a ring around the object, upright (camera y axis along the scene's +y, i.e. down)."""
    centre = torch.tensor(SCENE_OFFSET)
    out = []
    for i in range(views):
        phi = 2 * math.pi * i / views
        pos = centre + SCENE_SCALE * torch.tensor([1.2 * math.cos(phi), -0.4, 1.2 * math.sin(phi)])
        z = torch.nn.functional.normalize(centre - pos, dim=0)  # forward
        y0 = torch.tensor([0.0, 1.0, 0.0])
        x = torch.nn.functional.normalize(torch.linalg.cross(y0, z), dim=0)
        y = torch.linalg.cross(z, x)
        R = torch.stack([x, y, z], 1)
        out.append(
            {
                "id": i,
                "img_name": f"{i:05d}",
                "width": 640,
                "height": 480,
                "position": pos.tolist(),
                "rotation": R.tolist(),
                "fy": 500.0,
                "fx": 500.0,
            }
        )
    path.write_text(json.dumps(out))
