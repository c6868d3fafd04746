"""Pinned rules of a captured scene used as written (`capture.fit = false`, `capture.scene._as_written`), round
ten: the PLY's coordinates are metres in the simulation frame, so nothing is cleaned, fitted or split off (no
background, no transform); the notes say so first, then how many unreadable rows the reader dropped (only when
there were any: none by default), then how many interior particles were filled. The interior is filled only when
fill_interior is on and the set has no interior particles yet (a PLY this package exported carries its own).
"""

from __future__ import annotations

import numpy as np
import torch
from plyfile import PlyData
from trainer_ply import SEMI_AXES, object_surface

from fracture_gs.capture import scene
from fracture_gs.config import SceneConfig
from fracture_gs.io.config import config_from_dict
from fracture_gs.io.ply import save_ply

AS_WRITTEN = "capture.fit = false: coordinates used as written"
CENTRE = (0.5, 0.5, 0.3)


def shell():
    gs, _ = object_surface(600, seed=3)  # a closed ellipsoid surface 0.5 × 0.3 × 0.24 m around the origin
    return gs.replace(means=gs.means + torch.tensor(CENTRE))


def config(fill: bool) -> SceneConfig:
    cfg = SceneConfig()
    cfg.fill_interior = fill
    cfg.capture.fit = False
    return cfg


def test_used_as_written_without_fill_says_only_that_and_keeps_every_gaussian():
    """fill_interior off, nothing unreadable (the default count): one note, the same Gaussians, no background, no
    transform, the config itself."""
    gs, cfg = shell(), config(False)
    out = scene._as_written(cfg, gs)
    assert out.notes == [AS_WRITTEN]
    assert out.gaussians is gs and out.background is None and out.transform is None and out.cfg is cfg


def test_unreadable_rows_are_counted_in_the_second_note():
    """3 rows dropped by the reader: the second note counts them and names the kinds of unreadable rows."""
    out = scene._as_written(config(False), shell(), 3)
    assert out.notes == [
        AS_WRITTEN,
        "dropped 3 unreadable Gaussians (NaN/inf, degenerate scales or zero rotations)",
    ]


def test_a_surface_without_interior_is_filled_and_one_with_interior_is_not():
    """fill_interior on: a closed ellipsoid surface gets interior particles inside it (centred on it within 1 cm,
    most of them inside the surface; the note counts them);
    the filled set, given again, already has an interior and comes back unchanged with no fill note."""
    gs = shell()
    out = scene._as_written(config(True), gs)
    added = int(out.gaussians.interior.sum())
    assert added > 0 and len(out.gaussians) == len(gs) + added
    assert out.notes == [AS_WRITTEN, f"filled {added} interior particles"]
    inner = out.gaussians.means[out.gaussians.interior]
    radius = (((inner - torch.tensor(CENTRE)) / torch.tensor(SEMI_AXES)) ** 2).sum(1).sqrt()  # 1 on the surface
    assert float(radius.median()) < 1.0
    assert float((inner.mean(0) - torch.tensor(CENTRE)).norm()) < 0.01
    again = scene._as_written(config(True), out.gaussians)
    assert again.gaussians is out.gaussians and again.notes == [AS_WRITTEN]


def test_resolve_with_fit_off_reports_the_rows_the_reader_dropped(tmp_path):
    """A PLY of 600 Gaussians whose 2 rows hold NaN positions, capture.fit = false: resolve keeps the other 598 at
    their written positions and its second note counts the 2 dropped."""
    gs = shell()
    save_ply(gs, tmp_path / "clean.ply")
    data = PlyData.read(str(tmp_path / "clean.ply"))  # a GaussianSet refuses NaN means: write them with plyfile
    for axis in "xyz":
        data["vertex"].data[axis][[5, 17]] = np.nan
    data.write(str(tmp_path / "s.ply"))
    doc = {"extends": "capture", "scene": str(tmp_path / "s.ply"), "fill_interior": False, "capture": {"fit": False}}
    out = scene.resolve(config_from_dict(doc), "cpu")
    keep = torch.ones(600, dtype=torch.bool)
    keep[[5, 17]] = False
    assert torch.equal(out.gaussians.means, gs.means[keep])
    assert out.notes == [AS_WRITTEN, "dropped 2 unreadable Gaussians (NaN/inf, degenerate scales or zero rotations)"]
    assert out.background is None and out.transform is None
