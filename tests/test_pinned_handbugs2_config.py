"""Hand-written bug campaign, round two: config validation, overrides and key combinations (`io.config`).

- Every component of render.background is range-checked, each named by its index.
- capture.rotation must be orthonormal in every column: RᵀR = I entry by entry, the third column's length too.
- topology.latch_frame may be the last frame (`frames`), not one past it.
- --resolution caps the width and the height alike (MAX_IMAGE_SIDE on a side).
- --preset rescales Δt with Δx (Δt ∝ Δx keeps the CFL number), an explicit grid's shape inversely.
- capture.up names its axis with its sign: a rotation that takes that axis to +z agrees with it, for all six.
"""

import pytest
from badinput import capture_doc, refused

from fracture_gs.errors import ConfigError
from fracture_gs.io.config import config_from_dict
from fracture_gs.io.config.combinations import UP_AXES
from fracture_gs.io.config.overrides import apply_overrides, parse_resolution
from fracture_gs.io.config.validate import MAX_IMAGE_SIDE

pytestmark = pytest.mark.usefixtures("one_thread")


@pytest.mark.parametrize("i", [0, 1, 2])
def test_each_background_component_is_range_checked(i):
    """A background of (1/2, 1/2, 1/2) with component i at 1.5 is refused naming render.background[i]; at 1 it loads."""
    bad = [0.5, 0.5, 0.5]
    bad[i] = 1.5
    refused({"extends": "bread", "render": {"background": bad}}, f"render.background[{i}]")
    bad[i] = 1.0
    assert config_from_dict({"extends": "bread", "render": {"background": bad}}).render.background[i] == 1.0


@pytest.mark.parametrize(
    "rotation",
    [
        [[1.0, 0, 0], [0, 1.0, 0], [0, 0, 0.0]],  # third column zero: det 0
        [[1.0, 0, 0], [0, 1.0, 0], [0, 0, 2.0]],  # third column of length 2
        [[2.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0]],  # first column of length 2
        [[1.0, 0, 0], [0, 0.5, 0], [0, 0, 1.0]],  # second column of length 1/2
    ],
)
def test_a_rotation_needs_unit_columns_every_one(rotation):
    """RᵀR differs from I on one diagonal entry only: refused naming capture.rotation."""
    refused(capture_doc(rotation=rotation), "capture.rotation")


def test_latch_frame_may_be_the_last_frame_and_not_one_past_it():
    """frames = 10: topology.latch_frame = 10 loads (the state after the last frame), 11 is refused naming the key."""
    doc = {"extends": "bread", "frames": 10, "topology": {"provider": "oracle", "latch_frame": 10}}
    assert config_from_dict(doc).topology.latch_frame == 10
    doc["topology"]["latch_frame"] = 11
    refused(doc, "topology.latch_frame")


@pytest.mark.parametrize("text", [f"{MAX_IMAGE_SIDE + 1}x64", f"64x{MAX_IMAGE_SIDE + 1}"])
def test_resolution_caps_each_side(text):
    """MAX_IMAGE_SIDE + 1 pixels on either side is refused naming --resolution; MAX_IMAGE_SIDE on both is taken."""
    with pytest.raises(ConfigError, match="--resolution"):
        parse_resolution(text)
    assert parse_resolution(f"{MAX_IMAGE_SIDE}x{MAX_IMAGE_SIDE}") == (MAX_IMAGE_SIDE, MAX_IMAGE_SIDE)


def test_the_paper_preset_halves_dt_with_dx_and_doubles_the_grid():
    """Δx 1/64 → 1/128 (ratio 1/2): Δt 1e-3 → 5e-4 and an explicit 32×40×48 grid → 64×80×96; back to small restores
    both."""
    sim = {"dx": 1 / 64, "dt": 1e-3, "grid": "explicit", "grid_shape": [32, 40, 48]}
    cfg = config_from_dict({"extends": "bread", "sim": sim})
    out = apply_overrides(cfg, preset="paper")
    assert out.sim.dx == 1 / 128
    assert out.sim.dt == pytest.approx(5e-4, rel=1e-12)
    assert tuple(out.sim.grid_shape) == (64, 80, 96)
    back = apply_overrides(out, preset="small")
    assert back.sim.dt == pytest.approx(1e-3, rel=1e-12) and tuple(back.sim.grid_shape) == (32, 40, 48)


def test_each_up_axis_is_its_signed_unit_vector():
    """UP_AXES: ±x, ±y, ±z name (±1, 0, 0), (0, ±1, 0), (0, 0, ±1); a rotation whose third row is that axis (it
    takes the axis to +z) loads beside capture.up = that axis."""
    want = {}
    for a, name in enumerate("xyz"):
        for sign in (1.0, -1.0):
            v = [0.0, 0.0, 0.0]
            v[a] = sign
            want[("+" if sign > 0 else "-") + name] = tuple(v)
    assert UP_AXES == want
    rows = {"+x": [[0, 1, 0], [0, 0, 1], [1, 0, 0]], "-y": [[1, 0, 0], [0, 0, 1], [0, -1, 0]]}
    for up, rotation in rows.items():
        cfg = config_from_dict(capture_doc(up=up, rotation=[[float(v) for v in r] for r in rotation]))
        assert cfg.capture.up == up
