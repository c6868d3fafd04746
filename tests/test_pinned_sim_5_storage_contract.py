"""The grid-storage interface (`sim/storage.py`): what every storage shares with the solver.

- Each implementation (`grid.slots.SlotStorage`, `boxes.storage.BoxStorage`) takes every call of the interface as
  the interface states it: the same parameters in the same order with the same defaults, any extra parameter
  optional. A caller written against `Storage` (the simulator's `self.storage`) gets the documented default,
  `only_fragment = −1` = every particle (fragment ids are ≥ 0, so 0 would be fragment 0's particles alone).
- The solver counters are four distinct int32 slots 0 … 3 that fill the `N_COUNTS` array exactly.
- `MAX_SLOTS` = 8, the compile-time bound on `sim.field_slots`: the solver accepts 2 … 8 and refuses 9 naming the
  key and the range; the config validator (which may not import `sim`) holds the same bound; and the kernels'
  per-node register vectors are sized by it.
"""

from __future__ import annotations

import inspect

import pytest
import warp as wp
from simutil import config

from fracture_gs.errors import SimulationError
from fracture_gs.io.config.validate import MAX_FIELD_SLOTS
from fracture_gs.sim import storage as S
from fracture_gs.sim.boxes.storage import BoxStorage
from fracture_gs.sim.grid.slots import SlotStorage
from fracture_gs.sim.simulator import Simulator, validate_sim_config

IMPLEMENTATIONS = (SlotStorage, BoxStorage)
EMPTY = inspect.Parameter.empty


def test_the_interface_is_the_seven_calls_of_a_substep_and_its_fit():
    """`Storage` is abstract in exactly fit, whole_grid, on_latch, p2g, update, g2p and graph_key, and both
    storages implement all of them (neither is abstract)."""
    want = {"fit", "whole_grid", "on_latch", "p2g", "update", "g2p", "graph_key"}
    assert set(S.Storage.__abstractmethods__) == want
    with pytest.raises(TypeError):
        S.Storage()
    for impl in IMPLEMENTATIONS:
        assert issubclass(impl, S.Storage) and not inspect.isabstract(impl), impl.__name__


@pytest.mark.parametrize("impl", IMPLEMENTATIONS, ids=lambda c: c.__name__)
@pytest.mark.parametrize("name", ["fit", "whole_grid", "on_latch", "p2g", "update", "g2p", "graph_key"])
def test_each_storage_takes_each_call_as_the_interface_states_it(impl, name):
    """Liskov for keyword and positional callers: the implementation's leading parameters are the interface's
    (names, kinds and defaults equal, in order); a parameter it adds has a default, so the interface's call
    still binds."""
    want = list(inspect.signature(getattr(S.Storage, name)).parameters.values())
    got = list(inspect.signature(getattr(impl, name)).parameters.values())
    assert len(got) >= len(want), (impl.__name__, name)
    for a, b in zip(want, got):
        assert (a.name, a.kind, a.default) == (b.name, b.kind, b.default), (impl.__name__, name, a, b)
    for extra in got[len(want) :]:
        assert extra.default is not EMPTY, f"{impl.__name__}.{name}: {extra.name} needs a default"


def test_a_substep_without_a_fragment_is_every_particle():
    """`only_fragment` defaults to −1 wherever a substep's transfer is called without it: the interface's p2g
    and g2p, both storages' and the simulator's public p2g / g2p. −1 is no fragment id (ids are ≥ 0), so the
    pass covers every particle; 0 would restrict it to fragment 0."""
    owners = [S.Storage, *IMPLEMENTATIONS, Simulator]
    for owner in owners:
        for name in ("p2g", "g2p"):
            default = inspect.signature(getattr(owner, name)).parameters["only_fragment"].default
            assert default == -1 and isinstance(default, int), (owner.__name__, name, default)


def test_the_counters_are_four_distinct_slots_filling_the_counts_array():
    """COUNT_CLAMPED, COUNT_ESCAPED, COUNT_SLOT_OVERFLOW and COUNT_POOL_OVERFLOW are 0, 1, 2, 3 in that order: each
    launch bumps its own int32 of the one `N_COUNTS` = 4 array, none past its end and none shared."""
    counters = [S.COUNT_CLAMPED, S.COUNT_ESCAPED, S.COUNT_SLOT_OVERFLOW, S.COUNT_POOL_OVERFLOW]
    assert counters == [0, 1, 2, 3]
    assert S.N_COUNTS == 4 == len(set(counters))


@pytest.mark.parametrize("slots, ok", [(1, False), (2, True), (8, True), (9, False)])
def test_field_slots_lie_in_two_to_max_slots(slots, ok):
    """The solver checks sim.field_slots against [2, MAX_SLOTS = 8] at both ends: 2 and 8 pass, 1 and 9 are
    refused with one sentence naming the key and the range."""
    assert S.MAX_SLOTS == 8
    cfg = config(16, field_slots=slots)
    if ok:
        validate_sim_config(cfg)
    else:
        with pytest.raises(SimulationError, match=rf"sim\.field_slots = {slots} must lie in \[2, 8\]"):
            validate_sim_config(cfg)


def test_the_config_validator_and_the_kernels_hold_the_solvers_bound():
    """io/config may not import sim, so it keeps its own copy of the bound: it must equal MAX_SLOTS (a config the
    validator passes must not be refused by the solver, nor one the kernels cannot hold be passed); the per-node
    register vectors of the pool pass and of the field metrics hold exactly MAX_SLOTS fields."""
    from fracture_gs.sim.grid import field_metrics_kernels as FM
    from fracture_gs.sim.grid import kernels as GK

    assert MAX_FIELD_SLOTS == S.MAX_SLOTS
    assert FM.vec_sd._length_ == S.MAX_SLOTS and FM.vec_sd._wp_scalar_type_ == wp.float64
    assert GK.mat_s3._shape_ == (S.MAX_SLOTS, 3)
    assert GK.vec_s._length_ == GK.vec_si._length_ == S.MAX_SLOTS
