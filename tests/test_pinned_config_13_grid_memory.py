"""Pinned rule of an explicit grid over `sim.max_grid_cells` (`io.config.validate`), round thirteen: the refusal states
the node count and the grid buffers' memory at 32 bytes a node (mass and momentum, 16 B, plus velocity, 16 B), in
GiB of 2³⁰ bytes, so the user can judge whether to raise the cap. Values computed by hand.
"""

from __future__ import annotations

import pytest

from fracture_gs.errors import ConfigError
from fracture_gs.io.config import config_from_dict


@pytest.mark.parametrize(
    "shape, nodes, gib",
    [
        ([1024, 1024, 1024], "1,073,741,824", "32"),  # 2³⁰ nodes × 32 B = 32 GiB
        ([512, 512, 600], "157,286,400", "4.69"),  # 157,286,400 × 32 / 2³⁰ = 4.6875
        ([257, 256, 256], "16,842,752", "0.502"),  # one plane over the default cap of 256³
    ],
)
def test_the_refusal_states_the_nodes_and_their_gib(shape, nodes, gib):
    """An explicit grid_shape over the cap names its node count with thousands separators and ≈ its memory in GiB
    (3 significant digits), then the two ways out."""
    with pytest.raises(ConfigError) as info:
        config_from_dict({"extends": "bread", "sim": {"grid": "explicit", "grid_shape": shape}})
    assert str(info.value) == (
        f"<dict>: sim.grid_shape = {shape} is {nodes} nodes, over sim.max_grid_cells = 16,777,216 (≈ {gib} GiB of "
        "grid buffers); use a coarser grid (raise sim.dx, fewer nodes) or raise sim.max_grid_cells if the memory is "
        "there."
    )


def test_a_grid_at_the_cap_is_accepted():
    """256³ nodes, exactly the default cap, is not refused for its size."""
    cfg = config_from_dict({"extends": "bread", "sim": {"grid": "explicit", "grid_shape": [256, 256, 256]}})
    assert tuple(cfg.sim.grid_shape) == (256, 256, 256)
