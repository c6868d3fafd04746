"""Pinned rules of the interior note of a captured scene (`capture.scene._fill` with the real `assets.fill_interior`),
round ten: the note gives the voxel spacing the kept fill used, in millimetres (Δx/2 when the finest fill closes);
a closed surface is filled with about volume / spacing³ particles drawn at most Δx/4 wide; an open surface
(a bowl) is simulated as a shell and the note says at which voxel size it was open and which keys close it; a set
with nothing the fill can use (every Gaussian fainter than capture.min_opacity) gets no particles and a voxel size
of 0 mm, never a negative one.

A small ellipsoid surface (semi-axes 20 × 12 × 9.6 mm, 3,000 Gaussians) and Δx = 1.998 mm, so Δx/2 = 0.999 mm: a
spacing off by 0.1 % would print as 1 mm. Each fill takes a fraction of a second.
"""

from __future__ import annotations

import math
import re

import torch
from trainer_ply import object_surface

from fracture_gs.capture import scene as S
from fracture_gs.config import CaptureConfig

DX = 0.001998
SHRINK = 0.08  # the 0.5 m test object made 40 mm long
FILLED = re.compile(
    r"interior: filled with (\d+) particles at 0\.999 mm spacing "
    r"\(the surface encloses (\d+) % of the solid it bounds\)"
)
OPEN = re.compile(
    r"interior: the surface is open at 0\.999 mm voxels \(it encloses (\d+) % of the solid it bounds\), so the object "
    r"is simulated as a shell as thick as its Gaussians \((\d+) particles added inside that shell\); to fill it as a "
    r"solid, raise capture\.fill_closing \(now 1\) or lower capture\.fill_threshold \(now 0\.2\)"
)


def small(open_shell: bool):
    gs, volume = object_surface(3000, seed=0, open_shell=open_shell)
    return gs.replace(means=gs.means * SHRINK, scales=gs.scales * SHRINK), volume * SHRINK**3


def test_a_closed_surface_is_filled_at_half_a_cell_and_the_note_gives_that_spacing():
    """The closed ellipsoid encloses more than a quarter of its solid at Δx/2, so that fill is kept: the note says
    0.999 mm; its particle count times (Δx/2)³ is the ellipsoid's volume within 10 %; the fill particles are at
    most Δx/4 wide and the surface Gaussians are returned unchanged."""
    gs, volume = small(False)
    notes = []
    out = S._fill(gs, CaptureConfig(), DX, notes, 100_000)
    added = int(out.interior.sum())
    m = FILLED.fullmatch(notes[0])
    assert len(notes) == 1 and m is not None, notes
    assert int(m.group(1)) == added and int(m.group(2)) >= 25
    assert math.isclose(added * (DX / 2) ** 3, volume, rel_tol=0.1)
    assert bool((out.scales[out.interior] <= torch.tensor(DX / 4, dtype=out.scales.dtype)).all())
    assert torch.equal(out.means[: len(gs)], gs.means) and torch.equal(out.scales[: len(gs)], gs.scales)


def test_an_open_surface_is_a_shell_and_the_note_gives_the_finest_voxel_size():
    """The bowl (upper half of the ellipsoid) encloses less than FILL_WARNING at every spacing, so the finest
    fill is kept and the note says the surface is open at 0.999 mm voxels, how many particles thicken the shell,
    and the two keys (with their values) that would close it."""
    gs, _ = small(True)
    notes = []
    out = S._fill(gs, CaptureConfig(), DX, notes, 100_000)
    m = OPEN.fullmatch(notes[0])
    assert len(notes) == 1 and m is not None, notes
    assert int(m.group(1)) < 100 * S.FILL_WARNING
    assert int(m.group(2)) == int(out.interior.sum()) > 0


def test_nothing_to_fill_adds_nothing_and_reports_a_zero_voxel_size():
    """Every Gaussian fainter than capture.min_opacity: the fill uses none, reports no spacing, and the object
    comes back without interior particles; the note gives 0 mm voxels, 0 % enclosed and 0 particles."""
    gs, _ = small(False)
    faint = gs.replace(opacities=torch.full_like(gs.opacities, 0.01))
    notes = []
    out = S._fill(faint, CaptureConfig(min_opacity=0.05), DX, notes, 100_000)
    assert len(out) == len(faint) and not bool(out.interior.any())
    assert notes == [
        "interior: the surface is open at 0 mm voxels (it encloses 0 % of the solid it bounds), so the object is "
        "simulated as a shell as thick as its Gaussians (0 particles added inside that shell); to fill it as a solid, "
        "raise capture.fill_closing (now 1) or lower capture.fill_threshold (now 0.2)"
    ]
