"""Pinned rules of a sweep's launch environment (`fracture_gs.sweep.distributed.launch_from_env` and `Launch`):
no torchrun variables is the one-process launch rank 0 of 1, local rank 0 of 1, no rendezvous; every bound of
RANK, WORLD_SIZE, LOCAL_RANK and LOCAL_WORLD_SIZE is checked on both sides, each with its own sentence.

Unit-level calls only: the environment is a plain dict.
"""

from __future__ import annotations

import dataclasses

import pytest

from fracture_gs.sweep import distributed as D

MASTER = {"MASTER_ADDR": "h", "MASTER_PORT": "1"}


def fields(launch: D.Launch) -> tuple:
    return dataclasses.astuple(launch)


def test_the_one_process_launch_is_rank_zero_of_one_on_local_gpu_zero():
    """Without torchrun's variables a sweep is one process: rank 0 of 1, local rank 0 of 1 (so --device cuda gives
    it cuda:0), no rendezvous, not distributed. The dataclass defaults are that launch, field by field (compared
    with literal numbers, not with another default-made Launch)."""
    assert fields(D.launch_from_env({})) == (0, 1, 0, 1, "")
    assert fields(D.Launch()) == (0, 1, 0, 1, "")
    assert D.Launch().tag == "[rank 0/1]" and not D.Launch().distributed
    # an empty variable is the same as an unset one
    empty = {"RANK": "", "WORLD_SIZE": "", "LOCAL_RANK": "", "LOCAL_WORLD_SIZE": ""}
    assert fields(D.launch_from_env(empty)) == (0, 1, 0, 1, "")


def test_the_local_rank_and_size_default_to_the_global_ones():
    """LOCAL_RANK unset means one node: the local rank is the global rank; LOCAL_WORLD_SIZE unset is WORLD_SIZE."""
    assert fields(D.launch_from_env({"RANK": "0", "WORLD_SIZE": "1"})) == (0, 1, 0, 1, "")
    three = D.launch_from_env({"RANK": "2", "WORLD_SIZE": "3", **MASTER})
    assert fields(three) == (2, 3, 2, 3, "h:1") and three.distributed and three.tag == "[rank 2/3]"
    node = D.launch_from_env({"RANK": "3", "WORLD_SIZE": "4", "LOCAL_RANK": "1", **MASTER})
    assert fields(node) == (3, 4, 1, 4, "h:1")


def test_world_size_below_one_is_refused_by_its_own_sentence():
    """WORLD_SIZE must be at least 1: 0 and -1 are refused naming WORLD_SIZE and the bound (not as a RANK outside
    an empty range); 1 is accepted."""
    for world in (0, -1):
        with pytest.raises(D.LaunchError) as info:
            D.launch_from_env({"RANK": "0", "WORLD_SIZE": str(world)})
        assert str(info.value).startswith(f"WORLD_SIZE={world} must be at least 1; start the ranks with torchrun")
    assert D.launch_from_env({"RANK": "0", "WORLD_SIZE": "1"}).world_size == 1


@pytest.mark.parametrize("rank, world, ok", [(-1, 2, False), (0, 2, True), (1, 2, True), (2, 2, False)])
def test_rank_must_lie_in_zero_to_world_size_minus_one(rank, world, ok):
    """RANK lies in 0..WORLD_SIZE-1: both ends are accepted, one step outside either end is refused with the
    range in the sentence."""
    env = {"RANK": str(rank), "WORLD_SIZE": str(world), **MASTER}
    if ok:
        assert D.launch_from_env(env).rank == rank
        return
    with pytest.raises(D.LaunchError, match=rf"^RANK={rank} is outside 0\.\.1 \(WORLD_SIZE=2\); start the ranks"):
        D.launch_from_env(env)


@pytest.mark.parametrize(
    "local_rank, local_world, ok",
    [
        (-1, 2, False),  # a negative local rank: no GPU -1
        (0, 2, True),  # the lower end
        (1, 2, True),  # the upper end: LOCAL_RANK = LOCAL_WORLD_SIZE - 1
        (2, 2, False),  # LOCAL_RANK = LOCAL_WORLD_SIZE
        (0, 0, False),  # no process on this node, yet this one runs here
        (0, 4, True),  # LOCAL_WORLD_SIZE = WORLD_SIZE: one node
        (0, 5, False),  # more processes on this node than in the whole launch
    ],
)
def test_local_rank_and_local_world_size_must_fit_the_world(local_rank, local_world, ok):
    """0 <= LOCAL_RANK < LOCAL_WORLD_SIZE <= WORLD_SIZE (WORLD_SIZE = 4 here): each inequality is accepted at its
    edge and refused one step past it, with one sentence giving the three numbers and the rule."""
    env = {"RANK": "1", "WORLD_SIZE": "4", "LOCAL_RANK": str(local_rank), "LOCAL_WORLD_SIZE": str(local_world)}
    env |= MASTER
    if ok:
        assert fields(D.launch_from_env(env)) == (1, 4, local_rank, local_world, "h:1")
        return
    with pytest.raises(D.LaunchError) as info:
        D.launch_from_env(env)
    assert str(info.value).startswith(
        f"LOCAL_RANK={local_rank} and LOCAL_WORLD_SIZE={local_world} do not fit WORLD_SIZE=4 "
        "(need 0 <= LOCAL_RANK < LOCAL_WORLD_SIZE <= WORLD_SIZE); start the ranks with torchrun"
    )


def test_a_negative_local_rank_of_a_one_process_launch_is_refused():
    """RANK=0 WORLD_SIZE=1 with LOCAL_RANK=-1 is refused (it would pick GPU cuda:-1), not accepted as rank 0."""
    with pytest.raises(D.LaunchError, match=r"^LOCAL_RANK=-1 and LOCAL_WORLD_SIZE=1 do not fit WORLD_SIZE=1 "):
        D.launch_from_env({"RANK": "0", "WORLD_SIZE": "1", "LOCAL_RANK": "-1"})


def test_only_a_launch_of_several_processes_needs_a_rendezvous():
    """WORLD_SIZE = 1 needs no MASTER_ADDR/PORT (its master is ""); WORLD_SIZE = 2 without either one is refused
    naming the missing variable; with both the master is ADDR:PORT."""
    assert D.launch_from_env({"RANK": "0", "WORLD_SIZE": "1", **MASTER}).master == ""
    for missing in ("MASTER_ADDR", "MASTER_PORT"):
        env = {"RANK": "0", "WORLD_SIZE": "2", **{k: v for k, v in MASTER.items() if k != missing}}
        with pytest.raises(D.LaunchError, match=rf"^WORLD_SIZE=2 but {missing} is not set; torchrun sets it"):
            D.launch_from_env(env)
    assert D.launch_from_env({"RANK": "1", "WORLD_SIZE": "2", **MASTER}).master == "h:1"
