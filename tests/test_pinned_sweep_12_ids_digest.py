"""The plan's digest of the cell list (`fracture_gs.sweep.driver.ids_digest`): rank 0 sends it with the plan and
every rank compares it with its own, so ranks that expanded the spec differently stop instead of running someone
else's cells. It must be the same on every machine and Python (SHA-256 of the ordered ids joined by commas,
never Python's salted `hash`), depend on the ids and their order only, and be 16 lowercase hex digits (64 bits).
"""

from __future__ import annotations

import dataclasses

from fracture_gs.sweep.driver import ids_digest, make_plan
from fracture_gs.sweep.expansion import Cell

A = Cell(0, "0123456789ab", "scene", {"kind": "scene", "x": 1}, {}, ("t",))
B = Cell(1, "ba9876543210", "accuracy", {"kind": "accuracy"}, {}, ("u",), cost=5.0)


def test_the_digest_is_a_fixed_sixteen_hex_digit_value():
    """Known values (hand-checked with `sha256sum`): "0123456789ab,ba9876543210" -> 1ea1fcb22466e4af, the
    reverse order -> 1c5214ca07334110, no cells (the empty string) -> e3b0c44298fc1c14."""
    assert ids_digest([A, B]) == "1ea1fcb22466e4af"
    assert ids_digest([B, A]) == "1c5214ca07334110"
    assert ids_digest([]) == "e3b0c44298fc1c14"


def test_the_digest_depends_on_ids_and_order_only():
    """Another index, kind, params, labels or cost with the same ids gives the same digest; one more cell,
    one cell less, or one id changed gives another."""
    a2 = dataclasses.replace(A, index=7, kind="accuracy", params={}, labels=("z",), cost=99.0)
    assert ids_digest([a2, B]) == ids_digest([A, B])
    others = {ids_digest(c) for c in ([A], [B], [A, B, A], [dataclasses.replace(A, id="0123456789ac"), B])}
    assert len(others) == 4 and ids_digest([A, B]) not in others


def test_the_plan_carries_the_digest_of_all_cells():
    """make_plan's digest is that of the whole cell list, cached cells included (every rank expands all)."""
    plan = make_plan([A, B], [{A.id: "ok"}, {}], 2, rerun_failed=False)
    assert plan["digest"] == "1ea1fcb22466e4af" and plan["cached"] == 1
