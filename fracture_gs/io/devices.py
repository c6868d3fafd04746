"""The device argument of the package's functions: `"cpu"`, `"cuda:N"` or a torch.device that exists here, or one
ArgumentError sentence naming the function and the argument (`io.ply` re-exports it; `GaussianSet.to` uses it
without importing the PLY reader)."""

from __future__ import annotations

import torch

from ..errors import ArgumentError


def as_device(where: str, device) -> torch.device:
    """A device argument (`"cpu"`, `"cuda:0"`, a torch.device), or an ArgumentError naming it."""
    try:
        dev = torch.device(device)
    except (RuntimeError, TypeError, ValueError):
        raise ArgumentError(
            f"{where}: device {device!r:.40} is not a torch device; pass 'cpu', 'cuda' or 'cuda:N'."
        ) from None
    if dev.type == "cuda":
        count = torch.cuda.device_count() if torch.cuda.is_available() else 0
        if (dev.index or 0) >= count:
            have = f"{count} CUDA device(s)" if count else "no CUDA device"
            raise ArgumentError(f"{where}: device {str(dev)!r} does not exist (this machine has {have}); pass 'cpu'.")
    elif dev.type != "cpu":
        raise ArgumentError(f"{where}: device {str(dev)!r} is not one this package runs on; pass 'cpu' or 'cuda:N'.")
    return dev
