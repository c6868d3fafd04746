"""What each transfer variant means, resolved once (the paper's branches, DESIGN.md "Transfer variants").

Every other module asks `variant_spec(name)` instead of testing variant names: the solver reads
`fields`, `per_fragment_pass`, `release` and `contact`; the config checks `needs_provider`; the
composer, tables and plots take the labels. A leaf module: no torch, no Warp.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal, get_args

from .errors import SimulationError

VariantName = Literal["baseline", "probe_latch", "stress_zero", "global_fragment_pass", "local_multifield", "full"]


@dataclass(frozen=True)
class VariantSpec:
    """One transfer variant: how P2G/G2P route particles after a latch, and how it is labelled."""

    name: str
    """Config name (`sim.variant`, `variants = [...]`)."""
    fields: Literal["shared", "per_fragment"]
    """After a latch: one shared grid field, or one field per fragment (fragment-conditioned P2G/G2P)."""
    per_fragment_pass: bool
    """After a latch: a full shared grid pass per fragment (the paper's Global Fragment Pass)."""
    release: bool
    """Band stress release (Eq. stress_release) after the latch."""
    contact: bool
    """Approach-only contact projection between fragment fields."""
    needs_provider: bool
    """Needs fragment labels, hence a fracture event provider (or a replayed topology)."""
    label: str
    """Name in the paper's tables and plots."""
    caption: str
    """Short caption in comparison videos."""
    transfer: str
    """How the transfer is described in Table 1."""
    passes: str
    """Particle passes per substep after the latch (P2G/G2P/per-fragment), Table 2."""

    @property
    def multifield(self) -> bool:
        """Fragment-conditioned transfer (one pass, one field per fragment)."""
        return self.fields == "per_fragment"


VARIANT_SPECS: dict[str, VariantSpec] = {
    s.name: s
    for s in (
        VariantSpec(
            "baseline",
            "shared",
            False,
            False,
            False,
            False,
            "Baseline",
            "baseline (shared field)",
            "Shared (Baseline)",
            "1/1/0",
        ),
        VariantSpec(
            "probe_latch",
            "shared",
            False,
            False,
            False,
            True,
            "Probe+Latch",
            "probe latch",
            "Shared (Probe+Latch)",
            "1/1/0",
        ),
        VariantSpec(
            "stress_zero",
            "shared",
            False,
            True,
            False,
            True,
            "Stress-Zero",
            "stress release",
            "Shared (Stress-Zero)",
            "1/1/0",
        ),
        VariantSpec(
            "global_fragment_pass",
            "shared",
            True,
            True,
            False,
            True,
            "Global Fragment Pass",
            "global fragment pass",
            "Per-fragment passes",
            "2/2/1",
        ),
        VariantSpec(
            "local_multifield",
            "per_fragment",
            False,
            True,
            False,
            True,
            "Multi-field, no contact",
            "local multifield",
            "Fragment-conditioned (no contact)",
            "1/1/0",
        ),
        VariantSpec(
            "full",
            "per_fragment",
            False,
            True,
            True,
            True,
            "FractureFields (Full)",
            "FractureFields",
            "Fragment-conditioned (Full)",
            "1/1/0",
        ),
    )
}
VARIANT_NAMES: tuple[str, ...] = get_args(VariantName)
assert VARIANT_NAMES == tuple(VARIANT_SPECS)


def variant_spec(name: str) -> VariantSpec:
    """The spec of a variant name; an unknown name is a one-sentence ValueError."""
    try:
        return VARIANT_SPECS[name]
    except KeyError:
        raise SimulationError(f"variant '{name}' is unknown; use one of {', '.join(VARIANT_NAMES)}") from None
