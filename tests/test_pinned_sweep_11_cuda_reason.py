"""`fracture_gs.sweep.distributed._cuda` says how many CUDA devices this rank sees and, when that matters, why: with
no usable CUDA the count is 0 and the reason names the cause (a CPU-only torch build, or a CUDA build without a
device or driver); with CUDA the reason is the CUDA_VISIBLE_DEVICES setting when one is exported (it is why a
node shows fewer GPUs than it has), and empty when none is, so `--device cuda` with too many ranks adds
"(CUDA_VISIBLE_DEVICES=...)" to its refusal only when the variable is set, never "CUDA_VISIBLE_DEVICES=None".

torch.cuda is replaced (no GPU is needed), so every branch runs on this CPU machine.
"""

from __future__ import annotations

import pytest
import torch

from fracture_gs.sweep import distributed as D

THREE = D.Launch(rank=0, world_size=3, local_rank=0, local_world_size=3, master="h:1")


def cuda(monkeypatch, available: bool, count: int = 0, build="12.4"):
    monkeypatch.setattr(torch.cuda, "is_available", lambda: available)
    monkeypatch.setattr(torch.cuda, "device_count", lambda: count)
    monkeypatch.setattr(torch.version, "cuda", build)


@pytest.mark.parametrize("visible", ["0,1", "", "GPU-5f1c"])
def test_an_exported_cuda_visible_devices_is_the_reason(monkeypatch, visible):
    """With CUDA and CUDA_VISIBLE_DEVICES exported (even empty), the count is torch's and the reason is
    `CUDA_VISIBLE_DEVICES=<its value>`; too many ranks for the GPUs are refused naming it in parentheses."""
    cuda(monkeypatch, True, 2)
    monkeypatch.setenv("CUDA_VISIBLE_DEVICES", visible)
    assert D._cuda() == (2, f"CUDA_VISIBLE_DEVICES={visible}")
    with pytest.raises(D.LaunchError) as info:
        D.resolve_device("cuda", THREE)
    assert str(info.value) == (
        f"3 ranks were started on this node but it has 2 GPU(s) (CUDA_VISIBLE_DEVICES={visible}); start one rank "
        "per GPU (torchrun --nproc-per-node 2) or use --device cpu."
    )


def test_without_cuda_visible_devices_there_is_no_reason_to_give(monkeypatch):
    """With CUDA and no CUDA_VISIBLE_DEVICES the reason is empty: the refusal of too many ranks has no
    parentheses (never "CUDA_VISIBLE_DEVICES=None"), and a rank that fits gets cuda:LOCAL_RANK."""
    cuda(monkeypatch, True, 4)
    monkeypatch.delenv("CUDA_VISIBLE_DEVICES", raising=False)
    assert D._cuda() == (4, "")
    cuda(monkeypatch, True, 2)
    with pytest.raises(D.LaunchError) as info:
        D.resolve_device("cuda", THREE)
    assert str(info.value) == (
        "3 ranks were started on this node but it has 2 GPU(s); start one rank per GPU "
        "(torchrun --nproc-per-node 2) or use --device cpu."
    )
    second = D.Launch(rank=1, world_size=2, local_rank=1, local_world_size=2, master="h:1")
    assert D.resolve_device("cuda", second) == "cuda:1" and D.resolve_device("auto", second) == "cuda:1"


@pytest.mark.parametrize(
    "build, why",
    [(None, "a CPU-only torch build"), ("12.4", "no CUDA device or driver")],
    ids=["cpu-build", "cuda-build"],
)
def test_without_cuda_the_count_is_zero_and_the_reason_names_the_build(monkeypatch, build, why):
    """torch.cuda.is_available() False: 0 devices (whatever device_count says and CUDA_VISIBLE_DEVICES holds),
    the reason says which of the two causes it is; auto is the CPU and cuda is refused with that reason."""
    cuda(monkeypatch, False, 3, build)
    monkeypatch.setenv("CUDA_VISIBLE_DEVICES", "0")
    reason = f"torch.cuda.is_available() is False: {why}"
    assert D._cuda() == (0, reason)
    assert D.resolve_device("auto", D.Launch()) == "cpu"
    with pytest.raises(D.LaunchError) as info:
        D.resolve_device("cuda", D.Launch())
    assert str(info.value) == (
        f"--device cuda was requested but this machine has no CUDA device ({reason}); use --device cpu."
    )
