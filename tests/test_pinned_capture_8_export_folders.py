"""Pinned rule of splat export (`capture.export.export_ply`), round eight: `--export-ply` writes into a folder
that may not exist yet, however deep (every missing parent is made; an existing one is fine), and the file
holds the simulated Gaussians then the static background, mapped back to the scene's frame when a transform
is given (means x ↦ s·x + t, scales × s).
"""

from __future__ import annotations

import torch

from fracture_gs.capture.export import export_ply
from fracture_gs.capture.transform import SceneTransform
from fracture_gs.io.formats import read_gaussians
from fracture_gs.io.gaussian_set import GaussianSet


def gaussians(means) -> GaussianSet:
    x = torch.tensor(means, dtype=torch.float32)
    n = len(x)
    quats = torch.zeros(n, 4)
    quats[:, 0] = 1.0
    return GaussianSet(x, quats, torch.full((n, 3), 0.01), torch.full((n,), 0.8), torch.zeros(n, 1, 3))


def test_export_makes_every_missing_folder_and_writes_object_then_background(tmp_path):
    """A path three folders below one that exists is written (the folders made); writing a second file into
    the now existing folder works too. Back from the file: the 2 simulated Gaussians then the 1 background
    Gaussian, each at 2·x + (1, 2, 3) with scales 0.02."""
    sim, bg = gaussians([[0.0, 0.0, 0.0], [0.5, 0.25, 0.125]]), gaussians([[1.0, 1.0, 1.0]])
    back_to_scene = SceneTransform(2.0, torch.eye(3, dtype=torch.float64), torch.tensor([1.0, 2.0, 3.0]).double())
    path = tmp_path / "out" / "frames" / "ply" / "frame_0003.ply"
    assert export_ply(path, sim, bg, back_to_scene) == path and path.is_file()
    back, dropped, _ = read_gaussians(path)
    assert dropped == 0
    assert back.means.tolist() == [[1.0, 2.0, 3.0], [2.0, 2.5, 3.25], [3.0, 4.0, 5.0]]
    assert torch.allclose(back.scales, torch.full((3, 3), 0.02))
    again = export_ply(path.with_name("frame_0004.ply"), sim, None, None)
    assert read_gaussians(again)[0].means.tolist() == sim.means.tolist()
