"""Pinned rule of the material regions' note (`capture.materials.apply_regions`), round ten: region i labels its
Gaussians REGION_LABEL + i, and the note lists every region in order with the Gaussians it holds after later
regions took theirs, its preset and that same label, so a user can find the label in the resolved config's
`material_map`. A region left empty by a later one is refused, naming its index.
"""

from __future__ import annotations

import pytest
import torch

from fracture_gs.capture.materials import PRESETS, apply_regions
from fracture_gs.config import REGION_LABEL, MaterialRegion, SceneConfig
from fracture_gs.errors import SceneError
from fracture_gs.io.gaussian_set import GaussianSet


def row(n: int) -> GaussianSet:
    """n Gaussians on the x axis at 0, 1, …, n − 1 (scene units)."""
    x = torch.zeros(n, 3)
    x[:, 0] = torch.arange(n, dtype=torch.float32)
    quats = torch.zeros(n, 4)
    quats[:, 0] = 1.0
    return GaussianSet(x, quats, torch.full((n, 3), 0.1), torch.full((n,), 0.9), torch.zeros(n, 1, 3))


def box(lo: float, hi: float, material: str) -> MaterialRegion:
    return MaterialRegion((lo, -1.0, -1.0), (hi, 1.0, 1.0), material)


def test_the_note_lists_each_region_with_its_count_preset_and_label():
    """Ten Gaussians at x = 0 … 9; regions [0, 4] wood, [3, 6] bread (taking 3 and 4 from the first) and [8, 9]
    ceramic: labels 1000 for 0–2, 1001 for 3–6, 1002 for 8–9, 0 for 7; the note says 3 wood (label 1000), 4
    bread (label 1001), 2 ceramic (label 1002), and each label's material_map entry has its preset's E."""
    cfg = SceneConfig()
    cfg.capture.regions = [box(0.0, 4.0, "wood"), box(3.0, 6.0, "bread"), box(8.0, 9.0, "ceramic")]
    gs = row(10)
    note = apply_regions(cfg, gs)
    L = REGION_LABEL
    assert gs.labels.tolist() == [L, L, L, L + 1, L + 1, L + 1, L + 1, 0, L + 2, L + 2]
    assert note == (
        f"material regions: 3 Gaussians wood (label {L}), 4 Gaussians bread (label {L + 1}), "
        f"2 Gaussians ceramic (label {L + 2})"
    )
    entries = {e.label: e.E for e in cfg.material_map}
    assert entries == {L: PRESETS["wood"].E, L + 1: PRESETS["bread"].E, L + 2: PRESETS["ceramic"].E}


def test_a_region_emptied_by_a_later_one_is_refused_by_its_index():
    """Region 1 ([2, 3]) lies inside region 2 ([1, 5]), which takes all its Gaussians: SceneError naming
    capture.regions[1], its box and its material, with the source prefix; region 0 is not named."""
    cfg = SceneConfig()
    cfg.capture.regions = [box(0.0, 0.0, "wood"), box(2.0, 3.0, "bread"), box(1.0, 5.0, "plant")]
    with pytest.raises(SceneError) as err:
        apply_regions(cfg, row(8), "scan.toml: ")
    msg = str(err.value)
    assert msg.startswith("scan.toml: capture.regions[1] (lower = [2.0, -1.0, -1.0], upper = [3.0, 1.0, 1.0])")
    assert "holds none of the object's 8 Gaussians" in msg and "'bread'" in msg and "regions[0]" not in msg
