"""The surface measure's depth inversion (`penetration.surface_depth`) in one Warp launch.

A particle whose ball of radius R is filled to a share c by another piece lies d = R·u behind that piece's flat
surface, where u solves F(u) = c for the kernel's half-space share

    F(u) = 1/2 + 35/32 · (u − u³ + 3u⁵/5 − u⁷/7),    u ∈ [−1, 1],

monotone in u. `penetration.depth_from_fraction` is the torch twin: 40 halvings of [−1, 1], about 600 elementwise
ops, each a launch on a GPU, every frame and every variant. Here each thread halves its own interval 40 times:
the same bisection and the same polynomial, one launch, nothing read back. The two agree to within rounding
(the powers may round differently by an ulp, which moves u by about that much; `tests/test_penetration_kernels.py`).
"""

from __future__ import annotations

import torch
import warp as wp

from ...runtime import ensure_warp, warp_stream

wp.set_module_options({"enable_backward": False})

HALVINGS = 40  # [−1, 1] halved 40 times: u to 2⁻⁴⁰


@wp.func
def half_space_share(u: wp.float64):
    """F(u) for u in [−1, 1]: the share of the kernel W ∝ (1 − r²/R²)² behind a flat face u·R in front of its centre."""
    u3 = u * u * u
    return wp.float64(0.5) + wp.float64(35.0 / 32.0) * (
        u - u3 + wp.float64(0.6) * wp.pow(u, wp.float64(5.0)) - wp.pow(u, wp.float64(7.0)) / wp.float64(7.0)
    )


@wp.kernel
def invert_half_space_share(share: wp.array(dtype=wp.float64), u: wp.array(dtype=wp.float64)):
    """u[i] with F(u[i]) = share[i] (clamped to [0, 1]), by bisection of [−1, 1]."""
    i = wp.tid()
    c = wp.clamp(share[i], wp.float64(0.0), wp.float64(1.0))
    lo = wp.float64(-1.0)
    hi = wp.float64(1.0)
    for _halving in range(HALVINGS):
        mid = wp.float64(0.5) * (lo + hi)
        if half_space_share(mid) < c:
            lo = mid
        else:
            hi = mid
    u[i] = wp.float64(0.5) * (lo + hi)


def depth_from_share(share: torch.Tensor) -> torch.Tensor:  # [E] float64 -> [E] float64 in [−1, 1]
    """u with F(u) = share (`penetration.depth_from_fraction`'s twin), on share's device, in one launch."""
    share = share.to(torch.float64).contiguous()
    u = torch.empty_like(share)
    if share.numel() == 0:
        return u
    ensure_warp()
    device = str(share.device)
    wp.launch(
        invert_half_space_share,
        dim=share.numel(),
        inputs=[wp.from_torch(share), wp.from_torch(u)],
        device=device,
        stream=warp_stream(device),
    )
    return u
