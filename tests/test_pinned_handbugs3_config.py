"""Hand-written bug campaign, round three: config validation, building and key combinations (`io.config`).

- With adaptive Δt a frame needs n = ⌈frame_dt / min(Δt, cfl·Δx/c)⌉ substeps, c = √((λ + 2μ)/ρ) the P-wave speed of
  each material (the default and every material_map entry, with the entry's own E, ν and density, ν = 0
  included); n = sim.max_substeps_per_frame loads, one more is refused naming the entry's key.
- Every normal a config gives is a unit vector once loaded: topology.normal, each oracle plane's
  (`[[topology.planes]]`, whose events record it as the plane's unit normal) and each plane boundary's.
- An oracle plane latches at a frame of the run, the last one (`frames`) included, like topology.latch_frame; one
  past it is refused (it was accepted silently and never cut; fixed with this round).
"""

import pytest
from badinput import refused

from fracture_gs.io.config import config_from_dict

pytestmark = pytest.mark.usefixtures("one_thread")


def _wave_doc(cap: int, nu: float, E: float, density: float = 1000.0) -> dict:
    """Δx = 1/64, cfl = 0.5, Δt = 1e-3, frame_dt = 0.01; the default material soft (E = 1e3 Pa, ν = 0.45); one map
    entry (label 1) with its own E, ν and density."""
    return {
        "extends": "bread",
        "frame_dt": 0.01,
        "sim": {"adaptive_dt": True, "dx": 1 / 64, "cfl": 0.5, "dt": 1e-3, "max_substeps_per_frame": cap},
        "material": {"E": 1e3, "nu": 0.45, "density": 1000.0},
        "material_map": [{"label": 1, "E": E, "nu": nu, "density": density}],
    }


@pytest.mark.parametrize(
    "nu,E,density",
    [(0.0, 1e7, 1000.0), (0.25, 1e7 * 5 / 6, 1000.0), (0.0, 4e7, 4000.0)],
    ids=["nu0", "nu_quarter", "dense"],
)
def test_a_map_entrys_substeps_come_from_its_own_poisson_ratio_and_density(nu, E, density):
    """Each entry's P-wave modulus λ + 2μ = E(1 − ν)/((1 + ν)(1 − 2ν)) is 1e7 Pa at ρ = 1000 (E = 1e7 at ν = 0;
    E = 1e7·5/6 at ν = 1/4; 4e7 at ν = 0 with ρ = 4000): c = 100 m/s, cfl·Δx/c = 0.5/64/100 s, so a 0.01 s frame
    needs exactly 128 substeps. A cap of 128 loads; 127 is refused naming material_map[0].E."""
    assert config_from_dict(_wave_doc(128, nu, E, density)).sim.max_substeps_per_frame == 128
    msg = refused(_wave_doc(127, nu, E, density), "material_map[0].E")
    assert "128" in msg and "max_substeps_per_frame" in msg


def test_every_normal_a_config_gives_is_unit_after_loading():
    """topology.normal (0, 3, 4) → (0, 0.6, 0.8); oracle planes (2, 0, 0) → (1, 0, 0) and (0, 0, −5) → (0, 0, −1);
    a plane boundary (0, 0, 7) → (0, 0, 1); a normal that is already unit is kept as written."""
    doc = {
        "extends": "bread",
        "topology": {
            "provider": "oracle",
            "normal": [0.0, 3.0, 4.0],
            "planes": [
                {"point": [0.5, 0.5, 0.2], "normal": [2.0, 0.0, 0.0], "latch_frame": 1},
                {"point": [0.5, 0.5, 0.2], "normal": [0.0, 0.0, -5.0], "latch_frame": 2},
                {"point": [0.5, 0.5, 0.2], "normal": [0.6, 0.0, 0.8], "latch_frame": 3},
            ],
        },
        "sim": {"boundaries": [{"type": "plane", "point": [0.0, 0.0, 0.1], "normal": [0.0, 0.0, 7.0]}]},
    }
    cfg = config_from_dict(doc)
    assert cfg.topology.normal == pytest.approx((0.0, 0.6, 0.8), abs=1e-15)
    got = [p.normal for p in cfg.topology.planes]
    for have, want in zip(got, [(1.0, 0.0, 0.0), (0.0, 0.0, -1.0), (0.6, 0.0, 0.8)]):
        assert have == pytest.approx(want, abs=1e-15)
    assert cfg.sim.boundaries[0].normal == pytest.approx((0.0, 0.0, 1.0), abs=1e-15)


def test_an_oracle_plane_may_latch_at_the_last_frame_and_not_one_past_it():
    """frames = 10: [[topology.planes]] latch_frame = 10 loads (as topology.latch_frame may), 11 is refused naming
    topology.planes[1].latch_frame (the plane would never cut); a plane timed by latch_time ignores latch_frame."""
    plane = {"point": [0.5, 0.5, 0.2], "normal": [1.0, 0.0, 0.0]}
    doc = {"extends": "bread", "frames": 10, "topology": {"provider": "oracle"}}
    ok = [{**plane, "latch_frame": 3}, {**plane, "latch_frame": 10}]
    cfg = config_from_dict({**doc, "topology": {"provider": "oracle", "planes": ok}})
    assert [p.latch_frame for p in cfg.topology.planes] == [3, 10]
    late = [{**plane, "latch_frame": 3}, {**plane, "latch_frame": 11}]
    msg = refused({**doc, "topology": {"provider": "oracle", "planes": late}}, "topology.planes[1].latch_frame")
    assert "11" in msg and "frames" in msg
    timed = [{**plane, "latch_frame": 11, "latch_time": 0.05}]
    assert config_from_dict({**doc, "topology": {"provider": "oracle", "planes": timed}}).topology.planes[0].latch_time
