"""Differentiable simulation: MLS-MPM frames as torch autograd operations (`DiffSimulator`), Warp
kernels with backward passes (`kernels.py`), a float64 torch twin of a frame for gradient checks
(`reference.py`)."""

from .solver import DiffSimulator, FramePlan

__all__ = ["DiffSimulator", "FramePlan"]
