"""Pinned rules of `--preset` on a loaded config (`fracture_gs.io.config.overrides.apply_overrides`): a config already
at the preset's Δx (to 1e-12 relative) is left bit for bit; one further off is moved to the preset's Δx exactly,
with Δt scaled by the same ratio; an explicit grid keeps its box by taking the nearest whole node count, never
fewer than 4, and a count the stencil cannot use is refused by the validator naming the axis and that count.

Expected values are hand computations (Δx ratios of powers of two, rounding n / 2), not calls of the code.
Unit-level: `config_from_dict` and `apply_overrides` only.
"""

from __future__ import annotations

import pytest

from fracture_gs.errors import ConfigError
from fracture_gs.io.config import apply_overrides, config_from_dict


def _config(**sim):
    return config_from_dict({"variants": ["baseline"], "sim": sim}, source="t.toml")


def test_a_config_within_1e_12_of_the_presets_dx_is_left_bit_for_bit():
    """Δx = 1/64 · (1 + 2e-13) is the small preset's Δx up to rounding: --preset small leaves Δx, Δt and the grid
    exactly as written (no 1-ulp drift that would change a cached sweep cell's parameters) and only records the
    preset's name; at 1e-9 off it is a real change: Δx becomes 1/64 exactly and Δt shrinks by the same ratio."""
    near = (1 / 64) * (1 + 2e-13)
    cfg = _config(dx=near, grid_shape=[40, 30, 20], dt=3e-4)
    out = apply_overrides(cfg, preset="small")
    assert (out.sim.dx, out.sim.dt, out.sim.grid_shape, out.preset) == (near, 3e-4, (40, 30, 20), "small")
    off = (1 / 64) * (1 + 1e-9)
    out = apply_overrides(_config(dx=off, grid_shape=[40, 30, 20], dt=3e-4), preset="small")
    assert out.sim.dx == 1 / 64 and out.sim.grid_shape == (40, 30, 20)
    assert out.sim.dt == pytest.approx(3e-4 / (1 + 1e-9), rel=1e-15) and out.sim.dt != 3e-4


@pytest.mark.parametrize("n, shrunk", [(10, 5), (11, 6), (12, 6), (200, 100)])
def test_halving_the_resolution_takes_the_nearest_whole_node_count(n, shrunk):
    """paper → small doubles Δx, so an explicit axis of n nodes becomes round(n / 2) (the same box to within half a
    cell) and Δt doubles (the same CFL number)."""
    cfg = _config(dx=1 / 128, grid_shape=[128, 64, n], wall_cells=0, dt=1e-4)
    out = apply_overrides(cfg, preset="small")
    assert out.sim.grid_shape == (64, 32, shrunk) and out.sim.dx == 1 / 64 and out.sim.dt == pytest.approx(2e-4)


@pytest.mark.parametrize(
    "dx, shape, dt, axis",
    [
        (1 / 128, [128, 64, 5], 1e-4, 2),  # 5 / 2 = 2.5 -> 2 -> floored at 4
        (1 / 128, [128, 64, 7], 1e-4, 2),  # 7 / 2 = 3.5 -> 4
        (1 / 1024, [5, 40, 40], 1e-5, 0),  # 5 / 16 -> 0 -> floored at 4
    ],
)
def test_an_axis_shrunk_below_the_stencil_is_refused_at_its_rescaled_count(dx, shape, dt, axis):
    """An explicit axis that --preset shrinks below the B-spline stencil's 5 nodes is refused by the validator,
    naming the axis, the rescaled count (never below 4, however far Δx moves: a count of 0 or 2 would be no grid)
    and the minimum, with the command line as the source."""
    with pytest.raises(ConfigError) as info:
        apply_overrides(_config(dx=dx, grid_shape=shape, wall_cells=0, dt=dt), preset="small")
    assert info.value.field == f"sim.grid_shape[{axis}]"
    assert str(info.value) == (
        f"command line: sim.grid_shape[{axis}] = 4 is too small for the B-spline stencil and 0 wall cells; use at "
        "least 5 nodes per axis."
    )
