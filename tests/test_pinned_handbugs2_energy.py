"""Hand-written bug campaign, round two: when a run is a closed system (`sim.diagnostics.energy.drivers_active`).

A frame whose substeps start in [t0, t1) is driven when a driving boundary's window [start, end] meets it:
start < t1 and end ≥ t0, both edges exact. A boundary whose window ends exactly at t0 acted in the substep starting
at t0 (its `end` is inclusive, as the grid operators treat it: `t > end` is off), so it drives that frame; one that
starts exactly at t1 does not drive the frame before. The windows are those `Boundaries.region_table` uses: an
impulse lasts max(end − start, Δt), a velocity override until end + Δt/2. Times are powers of two (exact).
"""

import pytest

from fracture_gs import sim as S
from fracture_gs.sim.diagnostics import energy as E

DT = 1 / 64


@pytest.mark.parametrize(
    "driver,end",
    [
        (S.CuboidBoundary(lower=(0, 0, 0), upper=(1, 1, 1), velocity=(0.5, 0, 0), start=0.25, end=0.5), 0.5),
        (S.SphereBoundary(center=(0, 0, 0), radius=0.25, velocity=(0, 0.5, 0), start=0.25, end=0.5), 0.5),
        (S.ParticleRegion(kind="impulse", upper=(1, 1, 1), delta_v=(0, 0, 1), start=0.25, end=0.5), 0.5),
        (S.ParticleRegion(kind="impulse", upper=(1, 1, 1), delta_v=(0, 0, 1), start=0.25, end=0.25), 0.25 + DT),
        (S.ParticleRegion(kind="velocity", upper=(1, 1, 1), velocity=(1, 0, 0), start=0.25, end=0.5), 0.5 + DT / 2),
    ],
)
def test_a_driver_drives_every_frame_its_window_meets_edges_included(driver, end):
    """Window [1/4, end]: the frame starting at `end` is driven, the one starting a substep later is not; the frame
    ending at 1/4 (substeps starting before it) is not driven, the one containing 1/4 is."""
    assert E.drivers_active([driver], end, end + 0.125, DT), "a frame starting where the window ends"
    assert not E.drivers_active([driver], end + DT, end + 0.125, DT), "a frame after the window"
    assert not E.drivers_active([driver], 0.125, 0.25, DT), "a frame that ends where the window starts"
    assert E.drivers_active([driver], 0.125, 0.25 + DT, DT), "a frame holding the window's start"
