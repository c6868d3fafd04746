"""Batched 3×3 polar rotations and singular values in Warp kernels, with float64 torch twins.

    F = U Σ Vᵀ (SVD),   R = U D Vᵀ with D = diag(1, 1, det(U Vᵀ)) on the smallest singular value

R is the rotation of the polar decomposition F = R S: the proper rotation closest to F in the
Frobenius norm (for det F < 0 the axis of the smallest singular value is flipped, the convention of
the fixed-corotated model). Each thread takes one matrix, converts it to float64, runs Warp's
Jacobi `svd3` twice (the second pass on the nearly diagonal Uᵀ F V refines to round-off) and writes
float32 or float64. Batched cuSOLVER spends 63 ms on 183k such matrices; one thread per matrix is
bandwidth-bound. Used for the per-frame SH rotation R(F) and for the singular values of the
diagnostics; `polar_rotation_reference` / `singular_values_reference` are the torch twins.
"""

from __future__ import annotations

import torch
import warp as wp

from .runtime import ensure_warp, warp_stream

wp.set_module_options({"enable_backward": False})


@wp.func
def _svd_refined(F: wp.mat33d):
    U, s, V = wp.svd3(F)
    U2, s2, V2 = wp.svd3(wp.transpose(U) * F * V)
    return U * U2, s2, V * V2


@wp.func
def _polar(F: wp.mat33d):
    U, s, V = _svd_refined(F)
    R = U * wp.transpose(V)
    if wp.determinant(R) < wp.float64(0.0):
        k = 0  # the smallest |σ|: flip that column of U
        for j in range(1, 3):
            if wp.abs(s[j]) < wp.abs(s[k]):
                k = j
        D = wp.identity(n=3, dtype=wp.float64)
        D[k, k] = wp.float64(-1.0)
        R = U * D * wp.transpose(V)
    return R


@wp.kernel
def polar_f32(F: wp.array(dtype=wp.mat33), R: wp.array(dtype=wp.mat33)):
    i = wp.tid()
    R[i] = wp.mat33(_polar(wp.mat33d(F[i])))


@wp.kernel
def polar_f64(F: wp.array(dtype=wp.mat33d), R: wp.array(dtype=wp.mat33d)):
    i = wp.tid()
    R[i] = _polar(F[i])


@wp.func
def _sorted_abs(s: wp.vec3d):
    a, b, c = wp.abs(s[0]), wp.abs(s[1]), wp.abs(s[2])
    if a < b:
        a, b = b, a
    if b < c:
        b, c = c, b
    if a < b:
        a, b = b, a
    return wp.vec3d(a, b, c)


@wp.kernel
def singular_f32(F: wp.array(dtype=wp.mat33), out: wp.array(dtype=wp.vec3)):
    i = wp.tid()
    U, s, V = _svd_refined(wp.mat33d(F[i]))
    out[i] = wp.vec3(_sorted_abs(s))


@wp.kernel
def singular_f64(F: wp.array(dtype=wp.mat33d), out: wp.array(dtype=wp.vec3d)):
    i = wp.tid()
    U, s, V = _svd_refined(F[i])
    out[i] = _sorted_abs(s)


def _launch(kernels: dict, F: torch.Tensor, out_shape: tuple) -> torch.Tensor:
    if F.dtype not in kernels:
        raise TypeError(f"expected float32 or float64 matrices, got {F.dtype}")
    ensure_warp()
    shape = F.shape[:-2]
    flat = F.detach().reshape(-1, 3, 3).contiguous()
    out = torch.empty((flat.shape[0],) + out_shape, dtype=F.dtype, device=F.device)
    if flat.shape[0]:
        kernel, mat, res = kernels[F.dtype]
        device = str(F.device)
        wp.launch(
            kernel,
            dim=flat.shape[0],
            inputs=[wp.from_torch(flat, dtype=mat)],
            outputs=[wp.from_torch(out, dtype=res)],
            device=device,
            stream=warp_stream(device),  # torch's current stream, from any thread
        )
    return out.reshape(shape + out_shape)


def polar_rotation(F: torch.Tensor) -> torch.Tensor:  # [..., 3, 3] -> [..., 3, 3]
    """Rotation R of F = R S (det R = +1), on F's device and in F's dtype (float32 or float64)."""
    return _launch(
        {torch.float32: (polar_f32, wp.mat33, wp.mat33), torch.float64: (polar_f64, wp.mat33d, wp.mat33d)}, F, (3, 3)
    )


def singular_values(F: torch.Tensor) -> torch.Tensor:  # [..., 3, 3] -> [..., 3]
    """Singular values of F, non-negative and sorted descending (as `torch.linalg.svdvals`)."""
    return _launch(
        {torch.float32: (singular_f32, wp.mat33, wp.vec3), torch.float64: (singular_f64, wp.mat33d, wp.vec3d)}, F, (3,)
    )


def polar_rotation_reference(F: torch.Tensor) -> torch.Tensor:  # [..., 3, 3] -> [..., 3, 3]
    """float64 torch twin of `polar_rotation` (LAPACK / cuSOLVER SVD)."""
    Fd = F.to(torch.float64)
    W, _, Vh = torch.linalg.svd(Fd)
    D = torch.ones(F.shape[:-2] + (3,), dtype=torch.float64, device=F.device)
    D[..., 2] = torch.where(torch.linalg.det(W @ Vh) < 0, -1.0, 1.0)
    return ((W * D[..., None, :]) @ Vh).to(F.dtype)


def singular_values_reference(F: torch.Tensor) -> torch.Tensor:  # [..., 3, 3] -> [..., 3]
    """float64 torch twin of `singular_values`."""
    return torch.linalg.svdvals(F.to(torch.float64)).to(F.dtype)
