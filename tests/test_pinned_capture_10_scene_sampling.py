"""Pinned rule of how many particles a captured scene simulates (`capture.scene.resolve` → `capture.sample`),
round ten: the particles are spaced Δx/2 (8 per grid cell, Δx = capture.size / cells across), so a dense
capture is thinned to one particle per occupied Δx/2 voxel, and every Gaussian rides one of them; a capture that
is not that dense (its Gaussians fill at least 80 % as many voxels as it has Gaussians) is simulated whole. The
particle note gives the spacing in millimetres.

A 400-Gaussian trainer-like PLY fitted to 0.5 m; the resolution step is replaced by a fixed number of cells
(pinned elsewhere) and nothing is filled, so each resolve takes a fraction of a second.
"""

from __future__ import annotations

import pytest
import torch
from trainer_ply import write_trainer_ply

from fracture_gs.capture import scene
from fracture_gs.capture.resolution import Resolution
from fracture_gs.io.config import config_from_dict


@pytest.fixture(scope="module")
def ply(tmp_path_factory):
    path, _ = write_trainer_ply(tmp_path_factory.mktemp("sampling"), n=400, floaters=0, far=0)
    return path


def voxels(means: torch.Tensor, h: float) -> torch.Tensor:  # [N, 3] -> [N, 3] int64
    return torch.floor(means.to(torch.float64) / h).to(torch.int64)


def resolve(monkeypatch, ply, cells: int):
    monkeypatch.setattr(scene, "choose_resolution", lambda obj, cap, device: Resolution(cells, 0.5 / cells, 0, "r", 9))
    doc = {
        "extends": "capture",
        "scene": str(ply),
        "fill_interior": False,
        "capture": {"load": "none", "ground": "none", "outlier_neighbours": 0, "up": "-y", "size": 0.5},
    }
    out = scene.resolve(config_from_dict(doc), "cpu")
    assert out.cfg.sim.dx == pytest.approx(0.5 / cells, rel=1e-12)
    return out, next(n for n in out.notes if n.startswith("particles:"))


@pytest.mark.parametrize("cells, mm", [(8, "31.2"), (10, "25")])
def test_a_dense_capture_simulates_one_particle_per_half_cell_voxel(monkeypatch, ply, cells, mm):
    """0.5 m over `cells` cells: Δx/2 = 31.25 or 25 mm. The simulated particles are fewer than the 400
    Gaussians, lie one in each Δx/2 voxel that holds a Gaussian (every such voxel has exactly one), every Gaussian
    rides its nearest particle, never farther than the voxel diagonal √3·Δx/2 (its own voxel holds one), and the
    note says "one per <Δx/2 in mm> mm voxel"."""
    out, note = resolve(monkeypatch, ply, cells)
    h = 0.5 * out.cfg.sim.dx
    gs = out.gaussians
    assert len(gs) == 400 and gs.carrier is not None
    particles = gs.carrier.particles.means
    occupied = torch.unique(voxels(gs.means, h), dim=0)
    assert len(particles) == len(occupied) < 400
    assert len(torch.unique(voxels(particles, h), dim=0)) == len(particles)  # one particle per voxel
    rides = particles[gs.carrier.index]  # [400, 3] the particle each Gaussian rides
    assert float((rides.double() - gs.means.double()).norm(dim=1).max()) <= 3**0.5 * h
    assert note == (
        f"particles: {len(particles)} simulated ({len(particles)} of 400 surface Gaussians, one per {mm} mm voxel, "
        "and 0 interior), carrying all 400 Gaussians"
    )


def test_a_capture_no_denser_than_half_a_cell_is_simulated_whole(monkeypatch, ply):
    """16 cells, Δx/2 = 15.6 mm: the 400 Gaussians occupy at least 320 (80 %) distinct Δx/2 voxels, so every
    Gaussian is a particle (no carrier), and the note says so with that spacing."""
    out, note = resolve(monkeypatch, ply, 16)
    assert len(torch.unique(voxels(out.gaussians.means, 0.5 / 32), dim=0)) >= 320
    assert len(out.gaussians) == 400 and out.gaussians.carrier is None
    assert note == "particles: all 400 Gaussians simulated (no denser than 15.6 mm spacing)"
