"""Pinned rules of the [sim] table's validation (`io.config.validate._check_sim`), round five: each bound at its
edge (the value at the bound accepted, one step past it refused) and the one-sentence message a user reads,
written out by hand: the key, the value as given, the bound, and the fix.

The substep cap's message states the substeps a frame would take, frame_dt / sim.dt, as a whole number; the cap
allows a relative 1e-9 of rounding (0.01 / 0.001 is 10.000000000000002 in floating point and fits a cap of 10).

Each case builds one config from a dict (milliseconds); nothing is simulated.
"""

from __future__ import annotations

import pytest

from fracture_gs.errors import ConfigError
from fracture_gs.io.config import config_from_dict

BASE = {"variants": ["baseline"]}


def build(sim: dict, **top):
    return config_from_dict({**BASE, **top, "sim": sim})


def refused(sim: dict, **top) -> ConfigError:
    with pytest.raises(ConfigError) as info:
        build(sim, **top)
    text = str(info.value)
    assert text.startswith("<dict>: ") and "\n" not in text
    return info.value


@pytest.mark.parametrize(
    "sim, top, field, message",
    [
        (
            {"dt": 0.0},
            {},
            "sim.dt",
            "sim.dt = 0.0 must be a positive finite number; give the substep in seconds, e.g. dt = 1e-4.",
        ),
        (
            {"dt": 0.011},
            {"frame_dt": 0.01},
            "sim.dt",
            "sim.dt = 0.011 is longer than frame_dt = 0.01; use a substep no longer than one frame.",
        ),
        (
            {"dt": 0.001, "max_substeps_per_frame": 9},
            {"frame_dt": 0.01},
            "sim.max_substeps_per_frame",
            "frame_dt / sim.dt = 10 substeps exceeds sim.max_substeps_per_frame = 9; raise max_substeps_per_frame "
            "or sim.dt.",
        ),
        (
            {"dt": 0.0005, "max_substeps_per_frame": 79},
            {"frame_dt": 0.04},
            "sim.max_substeps_per_frame",
            "frame_dt / sim.dt = 80 substeps exceeds sim.max_substeps_per_frame = 79; raise max_substeps_per_frame "
            "or sim.dt.",
        ),
        (
            {"cfl": 1.5},
            {},
            "sim.cfl",
            "sim.cfl = 1.5 is outside [1e-12, 1.0]; use a CFL number in (0, 1], e.g. cfl = 0.4.",
        ),
        (
            {"cfl": 0.0},
            {},
            "sim.cfl",
            "sim.cfl = 0.0 is outside [1e-12, 1.0]; use a CFL number in (0, 1], e.g. cfl = 0.4.",
        ),
        (
            {"dx": 0.0},
            {},
            "sim.dx",
            "sim.dx = 0.0 must be a positive finite number; give the grid spacing in metres, e.g. dx = 0.015625.",
        ),
        ({"wall_cells": -1}, {}, "sim.wall_cells", "sim.wall_cells = -1 must be at least 0; use 0 or more cells."),
        (
            {"grid_shape": [8, 7, 8]},
            {},
            "sim.grid_shape[1]",
            "sim.grid_shape[1] = 7 is too small for the B-spline stencil and 3 wall cells; use at least 8 nodes per "
            "axis.",
        ),
        (
            {"grid_shape": [5, 5, 4], "wall_cells": 1},
            {},
            "sim.grid_shape[2]",
            "sim.grid_shape[2] = 4 is too small for the B-spline stencil and 1 wall cells; use at least 5 nodes per "
            "axis.",
        ),
        (
            {"grid_shape": [4, 5, 5], "wall_cells": 0},
            {},
            "sim.grid_shape[0]",
            "sim.grid_shape[0] = 4 is too small for the B-spline stencil and 0 wall cells; use at least 5 nodes per "
            "axis.",
        ),
        (
            {"grid_margin": -0.1},
            {},
            "sim.grid_margin",
            "sim.grid_margin = -0.1 must be at least 0.0; use a non-negative fraction, e.g. grid_margin = 0.5.",
        ),
        (
            {"max_grid_cells": 124},
            {},
            "sim.max_grid_cells",
            "sim.max_grid_cells = 124 must be at least 125; allow at least 5×5×5 nodes.",
        ),
        (
            {"grid_bounds": [[0.0, 0.0, 1.0], [1.0, 1.0, 1.0]]},
            {},
            "sim.grid_bounds.lower",
            "sim.grid_bounds.lower [0.0, 0.0, 1.0] is not below sim.grid_bounds.upper [1.0, 1.0, 1.0] on every "
            "axis; swap or fix the corners so lower < upper.",
        ),
        (
            {"restitution": 1.01},
            {},
            "sim.restitution",
            "sim.restitution = 1.01 is outside [0.0, 1.0]; use a restitution in [0, 1].",
        ),
        (
            {"restitution": -0.01},
            {},
            "sim.restitution",
            "sim.restitution = -0.01 is outside [0.0, 1.0]; use a restitution in [0, 1].",
        ),
        (
            {"eps_mass": -1e-9},
            {},
            "sim.eps_mass",
            "sim.eps_mass = -1e-09 must be at least 0.0; use a non-negative threshold, e.g. eps_mass = 1e-3.",
        ),
        (
            {"eps_band": -1e-6},
            {},
            "sim.eps_band",
            "sim.eps_band = -1e-06 must be at least 0.0; use a non-negative threshold, e.g. eps_band = 1e-3.",
        ),
        (
            {"field_slots": 1},
            {},
            "sim.field_slots",
            "sim.field_slots = 1 is outside [2, 8]; use 2 to 8 fields per node.",
        ),
        (
            {"field_slots": 9},
            {},
            "sim.field_slots",
            "sim.field_slots = 9 is outside [2, 8]; use 2 to 8 fields per node.",
        ),
        (
            {"max_fragments": 1},
            {},
            "sim.max_fragments",
            "sim.max_fragments = 1 is outside [2, 4096]; use 2 to 4096 fragments.",
        ),
        (
            {"max_fragments": 4097},
            {},
            "sim.max_fragments",
            "sim.max_fragments = 4097 is outside [2, 4096]; use 2 to 4096 fragments.",
        ),
        (
            {"contact": {"friction": -0.1}},
            {},
            "sim.contact.friction",
            "sim.contact.friction = -0.1 must be at least 0.0; use a non-negative Coulomb coefficient.",
        ),
        (
            {"contact": {"fill": 0.0}},
            {},
            "sim.contact.fill",
            "sim.contact.fill = 0.0 must be a positive finite number; use a fraction of a full node's mass, e.g. "
            "fill = 0.5.",
        ),
    ],
)
def test_a_sim_value_past_its_bound_is_refused_in_one_sentence(sim, top, field, message):
    """A [sim] value one step past its bound is refused naming the key, the value, the bound and the fix."""
    err = refused(sim, **top)
    assert err.field == field
    assert str(err) == f"<dict>: {message}"


@pytest.mark.parametrize(
    "sim, top",
    [
        ({"dt": 0.01}, {"frame_dt": 0.01}),  # one substep a frame
        ({"dt": 0.001, "max_substeps_per_frame": 10}, {"frame_dt": 0.01}),  # 10.000000000000002 fits 10
        ({"dt": 0.01 / (10 * (1 + 1e-10)), "max_substeps_per_frame": 10}, {"frame_dt": 0.01}),
        ({"cfl": 1.0}, {}),
        ({"cfl": 1e-12}, {}),
        ({"wall_cells": 0, "grid_shape": [5, 5, 5]}, {}),
        ({"wall_cells": 1, "grid_shape": [5, 5, 5], "max_grid_cells": 125}, {}),
        ({"wall_cells": 3, "grid_shape": [8, 8, 8]}, {}),
        ({"grid_margin": 0.0, "restitution": 0.0, "eps_mass": 0.0, "eps_band": 0.0}, {}),
        ({"restitution": 1.0}, {}),
        ({"grid_bounds": [[0.0, 0.0, 0.0], [1.0, 1.0, 1e-9]]}, {}),
        ({"field_slots": 2, "max_fragments": 2}, {}),
        ({"field_slots": 8, "max_fragments": 4096}, {}),
        ({"contact": {"friction": 0.0, "fill": 1e-9}}, {}),
    ],
)
def test_a_sim_value_at_its_bound_is_accepted(sim, top):
    """The edge values themselves are valid, and come back as given."""
    cfg = build(sim, **top)
    for key, value in sim.items():
        got = getattr(cfg.sim, key)
        if key == "contact":
            assert {k: getattr(got, k) for k in value} == value
        elif isinstance(value, list):
            assert [list(v) if isinstance(v, tuple) else v for v in got] == value
        else:
            assert got == value


def test_the_substep_cap_allows_only_rounding():
    """frame_dt / sim.dt just 1e-8 (relative) over the cap is refused; 1e-10 over is rounding and passes."""
    dt = 0.01 / (10 * (1 + 1e-8))
    assert refused({"dt": dt, "max_substeps_per_frame": 10}, frame_dt=0.01).field == "sim.max_substeps_per_frame"
    assert build({"dt": 0.01 / (10 * (1 + 1e-10)), "max_substeps_per_frame": 10}, frame_dt=0.01).sim.dt < 0.001
