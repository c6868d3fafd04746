"""The render-sim job package: one context, one result, one summary type, and flags held to their TOML keys.

summary.json is read by the CLI, the sweeps, the paper's experiments and users' scripts: its keys and their
order are a contract (`VariantSummary.as_dict`, `RunSummary.as_dict`). Every command-line override goes through
the same type checks and validation as the TOML key it sets (`apply_overrides(keys=...)`), so a flag cannot
reach the run with a value the file would refuse."""

from __future__ import annotations

import pytest

from fracture_gs import cli
from fracture_gs import render_sim as job_package
from fracture_gs.errors import ConfigError
from fracture_gs.io.config import apply_overrides, load_config
from fracture_gs.render_sim import RunSummary, summarize

BASE_KEYS = ["variant", "status", "frames", "substeps", "wall_s", "substeps_per_s", "latch", "energy"]
AFTER_LATCH_KEYS = [
    "mixing_counterfactual_mean",
    "mixing_counterfactual_max",
    "mixing_realized_mean",
    "mixing_realized_max",
    "shared_support_pct_mean",
    "mass_residual_max",
    "opening",
    "separated",
    "reapproach",
    "stringing",
    "penetration_max",
    "identity_crossing_max",
    "fragments",
    "fragment_crossing_max",
    "fragment_penetration_max",
    "collider_crossing_max",
    "slot_overflow",
    "first_contact_time",
    "cp_momentum_residual",
    "rel_normal_velocity_after",
    "max_delta_vt",
]
PLANE_KEYS = ["plane_first_contact", "plane_penetration", "plane_max_vt_near", "plane_max_vn_post"]
PLANE_KEYS += ["plane_momentum_residual"]


def _row(frame: int, latched: bool, **extra) -> dict:
    row = {"frame": frame, "substeps": 10 * frame, "latched": latched}
    if latched:
        row.update(
            mixing_counterfactual=0.2 * frame,
            mixing_realized=0.0,
            shared_support_pct=4.0,
            mass_residual=[1e-7, 2e-7 * frame],
            opening=0.5 * frame,
            separated=frame > 2,
            reapproach=0.1,
            stringing=0.01 * frame,
            penetration=0.05,
            identity_crossing=frame,
            fragments=2,
            slot_overflow=1,
            first_contact_time=None,
        )
    row.update(extra)
    return row


def test_a_variant_summary_keeps_summary_json_keys_in_order():
    """Before a latch a summary holds the base keys only; after one, the after-latch numbers follow in their fixed
    order; a plane-contact scene adds its keys last; the job's piece gap and interrupt flag come at the end. The
    numbers are the rows' last value, mean or maximum as named."""
    rows = [_row(0, False), _row(1, False, latch={"latch_frame": 1}), _row(2, True), _row(3, True)]
    early = summarize("full", rows[:1], "ok", 2.0)
    assert list(early.as_dict()) == BASE_KEYS
    s = summarize("full", rows, "ok", 2.0)
    assert list(s.as_dict()) == BASE_KEYS + AFTER_LATCH_KEYS
    d = s.as_dict()
    assert d["latch"] == {"latch_frame": 1} and d["substeps_per_s"] == 15.0
    assert (
        d["mixing_counterfactual_mean"] == pytest.approx(0.5) and d["mixing_counterfactual_max"] == 0.6000000000000001
    )
    assert d["opening"] == 1.5 and d["separated"] is True and d["identity_crossing_max"] == 3
    assert d["mass_residual_max"] == pytest.approx(6e-7) and d["slot_overflow"] == 2 and d["fragment_crossing_max"] == 0
    plane = {k: 0.0 for k in ("plane_penetration", "plane_max_vt_near", "plane_max_vn_post", "plane_momentum_residual")}
    with_plane = summarize("full", rows[:-1] + [_row(3, True, plane_first_contact=0.1, **plane)], "ok", 2.0)
    with_plane.piece_gap, with_plane.interrupted = 0.0, False
    assert list(with_plane.as_dict()) == BASE_KEYS + AFTER_LATCH_KEYS + PLANE_KEYS + ["piece_gap", "interrupted"]


def test_the_run_summary_writes_every_field_but_the_profile():
    """summary.json holds the run's fields in order; the profile stays in memory (profile.md holds it)."""
    run = RunSummary("n", "bread", "small", "cpu", 10, [], 3, 0.01, [{"variant": "full"}], True, "/tmp/x", "profile")
    assert list(run.as_dict()) == [
        "name",
        "scene",
        "preset",
        "device",
        "particles",
        "capture",
        "frames",
        "frame_dt",
        "variants",
        "interrupted",
        "out_dir",
    ]


def test_particles_on_the_command_line_is_held_to_the_configs_cap(monkeypatch, capsys):
    """--particles on a built-in scene is validated as the `particles` key is: beyond the cap it is refused (exit
    2, one sentence naming the key) before anything runs."""

    def never(*args, **kwargs):
        raise AssertionError("the run started with a refused particle count")

    monkeypatch.setattr(job_package, "run_render_sim", never)
    code = cli.main(["render-sim", "bread", "--particles", "200000000", "--device", "cpu"])
    err = capsys.readouterr().err
    assert code == 2 and "particles" in err and "Traceback" not in err


def test_override_keys_go_through_the_file_readers_checks():
    """A dotted key set from the command line is type-checked and range-checked as in a TOML file: a wrong type or
    an unknown key is a ConfigError naming it, a good value is set, and None leaves the key alone."""
    cfg = load_config("bread")
    out = apply_overrides(cfg, keys={"particles": 3000, "sim.particle_order": "cell", "capture.load": None})
    assert out.particles == 3000 and out.sim.particle_order == "cell" and out.capture.load == cfg.capture.load
    with pytest.raises(ConfigError, match="sim.particle_order"):
        apply_overrides(cfg, keys={"sim.particle_order": "sideways"})
    with pytest.raises(ConfigError, match="particles"):
        apply_overrides(cfg, keys={"particles": "many"})
    with pytest.raises(ConfigError, match="particle_order"):
        apply_overrides(cfg, keys={"sim.particle_ordr": "cell"})
    with pytest.raises(ConfigError, match="particles"):
        apply_overrides(cfg, keys={"particles": 0})
