"""Batched 3×3 polar rotations and singular values in Warp kernels, with float64 torch twins.

    F = U Σ Vᵀ (SVD),   R = U D Vᵀ with D = diag(1, 1, det(U Vᵀ)) on the smallest singular value

R is the rotation of the polar decomposition F = R S: the proper rotation closest to F in the
Frobenius norm (for det F < 0 the axis of the smallest singular value is flipped, the convention of
the fixed-corotated model). Each thread takes one matrix and converts it to float64. Where det F > 0
and F is not nearly flat, R comes from scaled Newton iterations (`polar_newton`, Higham 1986), about
five times cheaper than the SVD; elsewhere from Warp's Jacobi `svd3` run twice (the second pass on the
nearly diagonal Uᵀ F V refines to round-off). Batched cuSOLVER was many times slower on the bread paper
preset's 183k matrices (most of the main job's time before this kernel); one thread per matrix is
bandwidth-bound. Used for the per-frame SH rotation R(F) and for the singular values of the
diagnostics; `polar_rotation_reference` / `singular_values_reference` are the torch twins.
"""

from __future__ import annotations

from typing import Any

import torch
import warp as wp

from .runtime import ensure_warp, warp_stream

EIGH_CHUNK = 32768
"""Batched CUDA eigh (cuSOLVER) fails for batches of ≥ 65,536 matrices in torch 2.11 + CUDA 13 (and with an
internal error for ~100k float64 3×3s on an H100): decompose in chunks of this many."""


def eigh_chunked(m: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:  # [N, 3, 3] -> ([N, 3], [N, 3, 3])
    """`torch.linalg.eigh` of a batch of symmetric matrices, EIGH_CHUNK at a time (ascending eigenvalues)."""
    if len(m) <= EIGH_CHUNK:
        return torch.linalg.eigh(m)
    parts = [torch.linalg.eigh(c) for c in m.split(EIGH_CHUNK)]
    return torch.cat([v for v, _ in parts]), torch.cat([e for _, e in parts])


wp.set_module_options({"enable_backward": False})

POLAR_ITERATIONS = 16  # Newton steps before giving up (converges in ≤ 8 up to a condition number of ~1e3)
POLAR_MIN_DET = 1e-3  # Newton only where det F > this · (‖F‖²_F / 3)^{3/2}: neither inverted nor nearly flat


@wp.func
def polar_newton(F: Any, tol: Any):
    """(R, converged) for F = R S by scaled Newton iterations X ← ½(ζ X + X⁻ᵀ/ζ), ζ = det(X)^{−1/3}
    (Higham 1986), X⁻ᵀ = cof(X)/det(X) from cross products of X's rows, until ‖X_{k+1} − X_k‖²_F < tol
    (X_{k+1} is then at rounding: the iteration converges quadratically). Generic over float32 and
    float64 (tol's type). Not converged where det F ≤ 0 or F is nearly flat: the caller takes the SVD."""
    one = type(tol)(1.0)
    scale = wp.ddot(F, F) / type(tol)(3.0)
    X = F
    converged = int(0)  # noqa: UP018 (a dynamic Warp variable)
    if wp.determinant(F) > type(tol)(POLAR_MIN_DET) * scale * wp.sqrt(scale):
        for _ in range(POLAR_ITERATIONS):
            r0 = wp.vector(X[0, 0], X[0, 1], X[0, 2])
            r1 = wp.vector(X[1, 0], X[1, 1], X[1, 2])
            r2 = wp.vector(X[2, 0], X[2, 1], X[2, 2])
            c0 = wp.cross(r1, r2)
            c1 = wp.cross(r2, r0)
            c2 = wp.cross(r0, r1)
            d = wp.dot(r0, c0)
            if not (d > type(tol)(0.0)):  # lost positivity (not in exact arithmetic): leave it to the SVD
                break
            zeta = wp.pow(d, type(tol)(-1.0 / 3.0))
            Y = type(tol)(0.5) * (zeta * X + (one / (zeta * d)) * wp.matrix_from_rows(c0, c1, c2))
            step = Y - X
            X = Y
            if wp.ddot(step, step) < tol:
                converged = 1
                break
    return X, converged


@wp.func
def _svd_refined(F: wp.mat33d):
    U, s, V = wp.svd3(F)
    U2, s2, V2 = wp.svd3(wp.transpose(U) * F * V)
    return U * U2, s2, V * V2


@wp.func
def _polar(F: wp.mat33d):
    R, converged = polar_newton(F, wp.float64(1e-24))
    if converged != 0:
        return R
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
