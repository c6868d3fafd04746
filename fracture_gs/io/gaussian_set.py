"""`GaussianSet`: a 3D Gaussian scene as torch tensors (the type io, assets and users share), and the rules
its values follow, checked where a set is made (`check_gaussians`): shapes [N, 3] / [N, 4] / [N, 3] / [N] /
[N, K, 3] with K = (degree+1)², one device, finite values, σ within SIGMA_RANGE (the PLY rule), quaternions
≠ 0, opacities in [0, 1], labels non-negative. A list or numpy array of numbers is taken as a tensor; any
other type, shape or value is one `ArgumentError` sentence naming the argument and the fix.
"""

from __future__ import annotations

import math
from dataclasses import MISSING, dataclass, field, fields, replace
from typing import Any, Optional

import numpy as np
import torch

from ..errors import ArgumentError
from .devices import as_device

SIGMA_RANGE = (1e-18, 1e18)  # σ whose σ² is a normal, finite float32 (the covariance stays invertible)


@dataclass
class GaussianSet:
    """N Gaussians with activated parameters (what a renderer consumes).

    A 3DGS PLY stores log-scales and logit-opacities; `fracture_gs.io.load_ply` activates them
    (exp, sigmoid) and `save_ply` inverts that. Interior fill particles are Gaussians too: they
    are simulated but not drawn unless a fracture exposes them (`interior`).
    """

    means: torch.Tensor  # [N, 3] world positions
    quats: torch.Tensor  # [N, 4] unit quaternions, wxyz
    scales: torch.Tensor  # [N, 3] standard deviations along the local axes (> 0)
    opacities: torch.Tensor  # [N] in (0, 1)
    sh: torch.Tensor  # [N, K, 3] SH coefficients, K = (degree+1)², DC first
    interior: Optional[torch.Tensor] = None  # [N] bool: interior fill particle (not drawn by default)
    labels: Optional[torch.Tensor] = None  # [N] int32 material label (material maps)
    extra: dict = field(default_factory=dict)  # name -> [N] tensor: other per-Gaussian properties
    carrier: Optional[Carrier] = None  # simulate carrier.particles, these Gaussians follow them (None: 1:1)

    def __post_init__(self):
        checked = check_gaussians(
            "GaussianSet",
            means=self.means,
            quats=self.quats,
            scales=self.scales,
            opacities=self.opacities,
            sh=self.sh,
            interior=self.interior,
            labels=self.labels,
        )
        for name, value in checked.items():
            setattr(self, name, value)
        n = self.means.shape[0]
        if self.interior is None:
            self.interior = torch.zeros(n, dtype=torch.bool, device=self.means.device)
        if self.labels is None:
            self.labels = torch.zeros(n, dtype=torch.int32, device=self.means.device)

    def __len__(self) -> int:
        return self.means.shape[0]

    @property
    def sh_degree(self) -> int:
        return int(round(self.sh.shape[1] ** 0.5)) - 1

    @property
    def device(self) -> torch.device:
        return self.means.device

    def to(self, device) -> GaussianSet:
        device = as_device("GaussianSet.to", device)
        moved = {f.name: getattr(self, f.name) for f in fields(self) if f.name not in ("extra", "carrier")}
        moved = {k: v.to(device) if torch.is_tensor(v) else v for k, v in moved.items()}
        carrier = self.carrier.to(device) if self.carrier is not None else None
        return GaussianSet._derived(**moved, extra={k: v.to(device) for k, v in self.extra.items()}, carrier=carrier)

    def subset(self, mask: torch.Tensor) -> GaussianSet:
        """The Gaussians selected by a boolean mask or index tensor (without a carrier: its map is per Gaussian)."""
        mask = _selection(mask, len(self), self.means.device)
        pick = {f.name: getattr(self, f.name)[mask] for f in fields(self) if f.name not in ("extra", "carrier")}
        return GaussianSet._derived(**pick, extra={k: v[mask] for k, v in self.extra.items()})

    @classmethod
    def _derived(cls, **values) -> GaussianSet:
        """A set made from rows of one already checked (moved to a device, or a subset): the same values, so
        `check_gaussians` (reductions over every Gaussian and a host sync) is not run a second time."""
        obj = cls.__new__(cls)
        for f in fields(cls):
            if f.name in values:
                setattr(obj, f.name, values[f.name])
            else:  # the fields with defaults (extra, carrier)
                setattr(obj, f.name, f.default_factory() if f.default is MISSING else f.default)
        return obj

    def rotations(self) -> torch.Tensor:  # [N, 3, 3]
        """Rotation matrices of the (normalized) wxyz quaternions."""
        return quat_to_matrix(self.quats)

    def covariances(self) -> torch.Tensor:  # [N, 3, 3]
        """Rest covariances Σ⁰ = R S Sᵀ Rᵀ."""
        M = self.rotations() * self.scales[:, None, :]
        return M @ M.transpose(1, 2)

    def replace(self, **changes) -> GaussianSet:
        return replace(self, **changes)


def _selection(mask: Any, n: int, device) -> torch.Tensor:
    """`GaussianSet.subset`'s argument: a bool mask of N entries, or integer indices in -N … N-1 (a list or numpy
    array is converted), else ArgumentError."""
    t = as_tensor("GaussianSet.subset", "mask", mask, "[N] bool or [M] int")
    if t.numel() == 0 and t.dim() == 1 and not isinstance(mask, torch.Tensor):
        t = t.long()  # `[]` (or an empty numpy array) selects nothing; torch reads an empty list as float
    if t.dtype == torch.bool:
        if tuple(t.shape) != (n,):
            raise ArgumentError(
                f"GaussianSet.subset: mask has shape {list(t.shape)}, not [N] with N = {n} (the number of Gaussians); "
                "pass one bool per Gaussian, or integer indices."
            )
    elif t.is_floating_point() or t.is_complex() or t.dim() != 1:
        raise ArgumentError(
            f"GaussianSet.subset: mask has dtype {t.dtype} and shape {list(t.shape)}; pass a bool mask [N] or "
            "integer indices [M]."
        )
    elif t.numel() and not bool(((t >= -n) & (t < n)).all()):
        raise ArgumentError(
            f"GaussianSet.subset: mask holds indices outside -{n} … {n - 1}; pass indices of Gaussians."
        )
    return t.to(device)


def quat_to_matrix(q: torch.Tensor) -> torch.Tensor:  # [N, 4] wxyz (any norm) -> [N, 3, 3]
    """Rotation matrices of wxyz quaternions (normalized first)."""
    w, x, y, z = torch.nn.functional.normalize(q, dim=-1).unbind(-1)
    return torch.stack(
        [
            1 - 2 * (y * y + z * z),
            2 * (x * y - w * z),
            2 * (x * z + w * y),
            2 * (x * y + w * z),
            1 - 2 * (x * x + z * z),
            2 * (y * z - w * x),
            2 * (x * z - w * y),
            2 * (y * z + w * x),
            1 - 2 * (x * x + y * y),
        ],
        dim=-1,
    ).reshape(-1, 3, 3)


def quat_mul(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:  # [M, 4] × [M, 4] -> [M, 4]
    """Hamilton product of wxyz quaternions."""
    aw, ax, ay, az = a.unbind(-1)
    bw, bx, by, bz = b.unbind(-1)
    return torch.stack(
        [
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ],
        dim=-1,
    )


@dataclass
class Carrier:
    """Fewer simulated particles than drawn Gaussians: the simulation runs on `particles`, and Gaussian g is
    carried by particle a = index[g] with that particle's affine motion, x_g = x_a + F_a (x⁰_g − x⁰_a) and
    F_g = F_a (so Σ_g = F_a Σ⁰_g F_aᵀ), together with its fragment and band. Built by `capture.sample`."""

    particles: GaussianSet  # [P] the simulated set (interior fill included)
    index: torch.Tensor  # [G] int64: the carrying particle of each Gaussian
    offset: torch.Tensor  # [G, 3] x⁰_g − x⁰_a [m]

    def to(self, device) -> Carrier:
        return Carrier(self.particles.to(device), self.index.to(device), self.offset.to(device))

    def reordered(self, order: torch.Tensor) -> Carrier:
        """The same carrier with its particles permuted to `particles[order]` (e.g. into grid-cell order)."""
        position = torch.empty_like(order)
        position[order] = torch.arange(len(order), device=order.device)
        return Carrier(self.particles.subset(order), position[self.index], self.offset)

    def carry(self, x: torch.Tensor, F: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Particle positions [P, 3] and deformation gradients [P, 3, 3] → each Gaussian's ([G, 3], [G, 3, 3])."""
        Fg = F.index_select(0, self.index)
        means = x.index_select(0, self.index) + (Fg @ self.offset.to(F.dtype)[:, :, None])[:, :, 0]
        return means, Fg


# ----------------------------------------------------------------------------- checks

_SHAPES = {"means": "[N, 3]", "quats": "[N, 4]", "scales": "[N, 3]", "opacities": "[N]", "sh": "[N, K, 3]"}


INT32_MAX = 2**31 - 1
"""The largest material label: labels are stored as int32 (`GaussianSet.labels`, the PLY's `fgs_label`)."""


def as_tensor(where: str, name: str, value: Any, shape: str) -> torch.Tensor:
    """`value` as a tensor: a tensor as it is, a list, tuple or numpy array of numbers converted
    (`torch.as_tensor`); anything else is an ArgumentError naming `where`'s argument `name`."""
    if torch.is_tensor(value):
        return value
    if isinstance(value, (list, tuple, np.ndarray, np.generic, int, float)) and not isinstance(value, bool):
        try:
            return torch.as_tensor(value)
        except (TypeError, ValueError, RuntimeError, OverflowError):
            pass
    raise ArgumentError(
        f"{where}: {name} must be numbers of shape {shape}, got {_describe(value)}; pass a torch tensor "
        f"(a list or numpy array of numbers is converted)."
    )


def _describe(value: Any) -> str:
    if isinstance(value, np.ndarray):
        return f"a numpy array of dtype {value.dtype}"
    if isinstance(value, (list, tuple)):
        return f"a {type(value).__name__} that is not a rectangular array of numbers"
    return f"a {type(value).__name__}" if value is not None else "None"


def _floating(where: str, name: str, t: torch.Tensor) -> torch.Tensor:
    """A real floating tensor: integers become float32; bool and complex are refused."""
    if t.is_floating_point():
        return t
    if t.dtype == torch.bool or t.is_complex():
        raise ArgumentError(
            f"{where}: {name} has dtype {t.dtype}; pass real numbers (float32), e.g. {name}.float() if they are."
        )
    return t.to(torch.float32)


def _shaped(where: str, name: str, t: torch.Tensor, dims: tuple, n: Optional[int]) -> None:
    """`t` has len(dims) dimensions, the first n (when given), the others dims[1:] (None: any size)."""
    want = list(dims)
    if n is not None:
        want[0] = n
    ok = t.dim() == len(dims) and all(w is None or s == w for s, w in zip(t.shape, want))
    if not ok:
        of = f" with N = {n} (the number of means)" if n is not None else ""
        raise ArgumentError(
            f"{where}: {name} has shape {list(t.shape)}, not {_SHAPES.get(name, '[N]')}{of}; pass one row per Gaussian."
        )


def check_gaussians(where: str, **arrays: Any) -> dict:
    """The Gaussian arrays given (means, quats, scales, opacities, sh, interior, labels; None skipped) as tensors
    that follow the module doc's rules, or ArgumentError: one sentence naming `where` (the function or class that
    received them), the argument, what is wrong and the fix. One host sync for all value checks."""
    out: dict = {}
    means = _floating(where, "means", as_tensor(where, "means", arrays["means"], "[N, 3]"))
    _shaped(where, "means", means, (None, 3), None)
    n, device = means.shape[0], means.device
    out["means"] = means
    for name, dims in (("quats", (None, 4)), ("scales", (None, 3)), ("opacities", (None,)), ("sh", (None, None, 3))):
        if arrays.get(name) is None:
            continue
        t = _floating(where, name, as_tensor(where, name, arrays[name], _SHAPES[name]))
        _shaped(where, name, t, dims, n)
        out[name] = t
    if "sh" in out:
        k = out["sh"].shape[1]
        if k < 1 or math.isqrt(k) ** 2 != k:
            raise ArgumentError(
                f"{where}: sh has K = {k} coefficients per channel; pass [N, (degree+1)², 3] (1, 4, 9 or 16)."
            )
    if arrays.get("interior") is not None:
        t = as_tensor(where, "interior", arrays["interior"], "[N] bool")
        if t.dtype != torch.bool:
            raise ArgumentError(f"{where}: interior has dtype {t.dtype}, not bool; pass a bool mask, e.g. mask != 0.")
        _shaped(where, "interior", t, (None,), n)
        out["interior"] = t
    if arrays.get("labels") is not None:
        t = as_tensor(where, "labels", arrays["labels"], "[N] int")
        if t.is_floating_point() or t.is_complex() or t.dtype == torch.bool:
            raise ArgumentError(f"{where}: labels has dtype {t.dtype}; pass integer material labels (int32).")
        _shaped(where, "labels", t, (None,), n)
        out["labels"] = t
    for name, t in out.items():
        if t.device != device:
            raise ArgumentError(
                f"{where}: {name} is on {t.device} but means on {device}; move them to one device (.to(means.device))."
            )
    _check_values(where, out)
    return out


def _value_rules(out: dict) -> list:
    """(argument, [N] or [N, ...] bool tensor of bad entries, what they are, the fix), in the order checked."""
    rules = [("means", ~torch.isfinite(out["means"]), "NaN or infinite values", "give finite positions")]
    if "quats" in out:
        q = out["quats"]
        # below a norm of 1e-12 torch's normalize (its eps) no longer makes a unit quaternion: the rotation is lost
        bad = ~torch.isfinite(q).all(-1) | (torch.linalg.vector_norm(q.double(), dim=-1) < 1e-12)
        rules.append(
            (
                "quats",
                bad,
                "zero or non-finite quaternions (or a norm below 1e-12)",
                "give rotations as unit wxyz quaternions",
            )
        )
    if "scales" in out:
        s = out["scales"]
        bad = ~(torch.isfinite(s) & (s >= SIGMA_RANGE[0]) & (s <= SIGMA_RANGE[1]))
        why = f"values outside [{SIGMA_RANGE[0]:g}, {SIGMA_RANGE[1]:g}] (or NaN)"
        rules.append(("scales", bad, why, "scales are standard deviations: pass torch.exp(log_scales)"))
    if "opacities" in out:
        o = out["opacities"]
        bad = ~((o >= 0) & (o <= 1))
        rules.append(("opacities", bad, "values outside [0, 1] (or NaN)", "pass torch.sigmoid(logits)"))
    if "sh" in out:
        rules.append(("sh", ~torch.isfinite(out["sh"]), "NaN or infinite coefficients", "give finite SH values"))
    if "labels" in out:
        lab = out["labels"]
        rules.append(("labels", lab < 0, "negative labels", "give non-negative material labels"))
        big = lab > INT32_MAX  # stored as int32: a larger label would wrap onto another one
        rules.append(("labels", big, f"labels above {INT32_MAX:,} (int32)", "give material labels that fit in int32"))
    return rules


def _check_values(where: str, out: dict) -> None:
    if len(out["means"]) == 0:
        return
    rules = [(name, bad.reshape(len(bad), -1).any(1), what, fix) for name, bad, what, fix in _value_rules(out)]
    counts = torch.stack([bad.sum() for _, bad, _, _ in rules]).tolist()  # one host sync
    for (name, bad, what, fix), count in zip(rules, counts):
        if count:
            row = int(bad.nonzero()[0, 0])
            value = out[name][row].detach()
            shown = f", {[round(v, 6) for v in value.reshape(-1).tolist()]}" if value.numel() <= 4 else ""
            raise ArgumentError(f"{where}: {name} has {count} row(s) with {what} (first: row {row}{shown}); {fix}.")
