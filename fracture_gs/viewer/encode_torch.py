"""The view record's frame and epoch bodies encoded as torch ops on the frame's device, byte for byte what
`format.encode_frame` / `format.encode_epoch` write from numpy, with one host copy per record.

Why: a run records every frame it draws (`record.FrameRecorder`). Converting each frame's centres and covariances
to float64 numpy arrays on the host and quantising them there took about 45 ms a frame at 183k Gaussians, on the
renderer's thread, which made a GPU run several times longer than its simulation. On the device the same
arithmetic is a handful of elementwise kernels, and only the 18 bytes per Gaussian of the record cross to the host.

Exactness: the centres are quantised in float64 with the numpy path's operations in its order (`torch.round` and
`np.rint` both round half to even). numpy converts float64 to float16 in one rounding; torch goes through float32,
which can round twice, so `half_exact` rounds to float16's precision in float64 first (exponent from `frexp`, the
mantissa rounded half to even to 11 bits, or to 2⁻²⁴ steps below float16's smallest normal), after which the cast
is exact. Bytes are little-endian, as the format says (every device torch runs on here is little-endian).
"""

from __future__ import annotations

import numpy as np
import torch

from ..runtime import device_constant
from .format import F16_CLIP, QUANT_STEPS

TRIU = (0, 1, 2, 4, 5, 8)  # xx, xy, xz, yy, yz, zz of a row-major 3×3 (`format.covariance_triu`)

F16_MIN_NORMAL = 2.0**-14


def half_exact(x: torch.Tensor) -> torch.Tensor:  # float64 [...] -> float16 [...]
    """float64 → float16 rounded once, to nearest with ties to even (numpy's `astype(np.float16)`), for |x| ≤ 65504
    and finite x."""
    mantissa, exponent = torch.frexp(x)  # x = m · 2^e, 0.5 ≤ |m| < 1
    normal = torch.ldexp(torch.round(torch.ldexp(mantissa, torch.full_like(exponent, 11))), exponent - 11)
    subnormal = torch.round(torch.ldexp(x, torch.full_like(exponent, 24))) * 2.0**-24
    return torch.where(x.abs() < F16_MIN_NORMAL, subnormal, normal).to(torch.float32).to(torch.float16)


def _half(x: torch.Tensor) -> torch.Tensor:  # float64 [...] -> float16 [...]
    """`half_exact` of x; on the CPU numpy's own float64 → float16 cast (the format's reference, one rounding),
    about ten times cheaper than `half_exact`'s frexp, ldexp and round passes."""
    if x.device.type == "cpu":
        out = torch.empty(x.shape, dtype=torch.float16)
        np.copyto(out.numpy(), x.numpy(), casting="same_kind")
        return out
    return half_exact(x)


def _bytes(t: torch.Tensor) -> torch.Tensor:  # [...] -> [numel · itemsize] uint8, little-endian
    return t.contiguous().view(torch.uint8).reshape(-1)


def frame_packed(means: torch.Tensor, cov: torch.Tensor, cov_unit: float) -> torch.Tensor:  # -> [24 + 18N] uint8
    """A frame record's box and body as one uint8 tensor on the frames' device, not yet copied to the host (the
    recorder appends its own bytes and copies the whole once): the 24 bytes of the centres' bounding box (lo, hi as
    float32), then the uint16 centres quantised in that box [N,3], then the float16 covariance upper triangles /
    cov_unit [N,6]. `means` [N,3] and `cov` [N,3,3] on any device."""
    m = torch.nan_to_num(means.detach().to(torch.float64), nan=0.0, posinf=0.0, neginf=0.0)  # [N,3]
    if m.shape[0]:
        lo, hi = m.min(0).values, m.max(0).values  # [3]
    else:
        lo = hi = torch.zeros(3, dtype=torch.float64, device=m.device)
    span = torch.where(hi > lo, hi - lo, torch.ones_like(hi))
    # the operations of round((m − lo) / span · QUANT_STEPS).clamp(0, QUANT_STEPS), in place on one temporary
    q = (m - lo).div_(span).mul_(QUANT_STEPS).round_().clamp_(0, QUANT_STEPS).to(torch.int32)  # [N,3] in 0 … 65535
    q16 = _bytes(q).view(-1, 4)[:, :2]  # [3N, 2]: each value's two low bytes, little-endian
    triu = device_constant(TRIU, torch.int64, cov.device)  # `covariance_triu`'s columns, 4x faster than [:, list]
    c = cov.detach().reshape(-1, 9).index_select(1, triu).to(torch.float64)  # [N,6], a new tensor (index_select)
    c.div_(cov_unit).nan_to_num_(nan=0.0, posinf=0.0, neginf=0.0).clamp_(-F16_CLIP, F16_CLIP)
    return torch.cat([_bytes(torch.cat([lo, hi]).to(torch.float32)), q16.reshape(-1), _bytes(_half(c))])


def epoch_body(rgb: torch.Tensor, flags: torch.Tensor, fragment: torch.Tensor) -> torch.Tensor:  # -> [6N] uint8
    """An epoch record's body on the device: colours [N,3] in [0,1] to uint8, flags [N] uint8, fragment ids [N]
    clipped to int16 — compared on the device with the last one, and copied to the host only when it changed."""
    rgb8 = torch.round(torch.nan_to_num(rgb.detach().to(torch.float64)).clamp(0.0, 1.0) * 255).to(torch.uint8)
    frag = fragment.detach().to(torch.int64).clamp(-1, 32767).to(torch.int16)
    return torch.cat([_bytes(rgb8), _bytes(flags.to(torch.uint8)), _bytes(frag)])
