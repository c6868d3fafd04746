"""Pinned rule of a captured scene's fragment capacity (`capture.scene.resolve`), round ten: the resolved config
leaves room for two fragment ids per allowed fracture event plus two, sim.max_fragments ≥ 2·topology.max_events
+ 2; a config that allows more keeps its own number (the capacity is raised, never lowered). The capture preset
allows 32 fragments.

A 400-Gaussian trainer-like PLY; the resolution step is replaced by a fixed 8 cells (pinned elsewhere) and nothing
is filled, so each resolve takes a fraction of a second.
"""

from __future__ import annotations

import pytest
from captureutil import fixed_resolution  # noqa: F401 - autouse: every capture here has 8 cells across
from trainer_ply import write_trainer_ply

from fracture_gs.capture import scene
from fracture_gs.io.config import config_from_dict


@pytest.fixture(scope="module")
def ply(tmp_path_factory):
    path, _ = write_trainer_ply(tmp_path_factory.mktemp("fragments"), n=400, floaters=0, far=0)
    return path


@pytest.mark.parametrize(
    "events, own, expected",
    [
        (1, None, 32),  # the preset's 32 is more than 2·1 + 2 = 4
        (15, None, 32),  # 2·15 + 2 = 32: equal, kept
        (16, None, 34),  # 2·16 + 2 = 34: raised
        (20, None, 42),
        (20, 8, 42),  # a small capacity of the config's own is raised too
        (20, 100, 100),  # a larger one is kept
        (3, 2, 8),  # the smallest capacity validation allows, raised to 2·3 + 2
    ],
)
def test_the_fragment_capacity_covers_two_pieces_per_event_plus_two(ply, events, own, expected):
    """sim.max_fragments after resolve = max(the config's, 2·topology.max_events + 2), checked on both sides of the
    preset's 32 and with a config's own capacity below and above the need."""
    doc = {
        "extends": "capture",
        "scene": str(ply),
        "fill_interior": False,
        "topology": {"max_events": events},
        "capture": {"load": "none", "ground": "none", "outlier_neighbours": 0, "up": "-y"},
    }
    if own is not None:
        doc["sim"] = {"max_fragments": own}
    cfg = scene.resolve(config_from_dict(doc), "cpu").cfg
    assert cfg.sim.max_fragments == expected
    assert cfg.topology.max_events == events
