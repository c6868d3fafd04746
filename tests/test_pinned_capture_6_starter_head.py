"""Pinned rules of the starter config's header (`capture.starter.starter_toml`), round six: the header names the
file and today's date, lists every automatic choice (the capture's notes, one `#   - ` line each, in order),
and lists the loads a user can switch to: every `capture.load` choice except `none`, which adds no load; the
body under it is a config that loads back to the very config the capture resolved.

Unit-level calls on a stand-in capture (notes + config): no PLY is read.
"""

from __future__ import annotations

import datetime
from types import SimpleNamespace
from typing import get_args

import tomllib

from fracture_gs.capture.starter import starter_toml
from fracture_gs.config import CuboidBoundary, LoadKind, SceneConfig
from fracture_gs.io.config import config_from_dict


def capture(notes=("fit: scale 0.5 m per scene unit", "load drop: falls from 0.1 m")) -> SimpleNamespace:
    cfg = SceneConfig(scene="scene.ply")  # [capture] keys act on a captured scene only
    cfg.frames, cfg.capture.load, cfg.variants = 7, "crush", ["baseline"]
    cfg.sim.boundaries = [CuboidBoundary(lower=(0.1, 0.2, 0.3), upper=(0.4, 0.5, 0.6), velocity=(0.0, 0.0, -0.2))]
    return SimpleNamespace(notes=list(notes), cfg=cfg)


def test_the_header_lists_the_choices_made_and_the_loads_to_switch_to():
    """The header's first lines name the PLY and today's date; each note is one `#   - ` line, in order; the
    last header line offers exactly the loads auto, pull, drop, impact, shoot and crush (every LoadKind but
    `none`, in the Literal's order)."""
    text = starter_toml(capture(), "scans/vase.ply")
    lines = text.splitlines()
    assert lines[0] == "# fracture-gs starter config for scans/vase.ply"
    assert lines[1].startswith(f"# written by `fracture-gs init` on {datetime.date.today().isoformat()}: ")
    at = lines.index("# What was chosen:")
    assert lines[at + 1 : at + 3] == ["#   - fit: scale 0.5 m per scene unit", "#   - load drop: falls from 0.1 m"]
    assert lines[at + 3] == "#"
    offered = [k for k in get_args(LoadKind) if k != "none"]
    assert offered == ["auto", "pull", "drop", "impact", "shoot", "crush"]
    assert '# capture.load = "auto", "pull", "drop", "impact", "shoot", "crush".' in lines
    assert sum('"none"' in line for line in lines[: lines.index("")]) == 0, "none adds no load: not offered"


def test_the_whole_starter_loads_back_to_the_captures_config():
    """The header is comments only and the body, every key with its documentation in comments, is TOML that
    loads back to the capture's own config (the frames, the load and the boundary table included)."""
    cap = capture()
    text = starter_toml(cap, "a.ply")
    back = config_from_dict(tomllib.loads(text), "starter.toml")
    assert back == cap.cfg
    assert back.frames == 7 and back.capture.load == "crush" and len(back.sim.boundaries) == 1
