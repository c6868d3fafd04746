"""The one frozen context of a render-sim run, and the one result its schedulers return.

`run_render_sim` prepares the scene once and makes a `RunContext`; each scheduler (in turn, in threads,
on several devices) takes that context and the metrics file and returns a `ScheduleResult`, so the job
reads every scheduler's outcome the same way.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Optional

if TYPE_CHECKING:
    import numpy as np

    from ..capture.scene import Capture
    from ..config import SceneConfig
    from ..io import GaussianSet
    from ..sim import Topology
    from .comparison import ComparisonVideo
    from .summary import VariantSummary


@dataclass(frozen=True)
class Export:
    """`--export-ply N`: every N-th frame of every variant as a splat file, in the scene's own frame."""

    every: int
    """Write frames 0, N, 2N, ... ."""
    capture: Capture
    """The prepared scene: its fit maps simulated positions back to the file's coordinates."""
    format: str
    """`ply`, `compressed-ply`, `splat` or `spz` (`io.formats.write_gaussians`)."""


@dataclass(frozen=True)
class RunContext:
    """What every scheduler of one run reads; made once, after the scene is prepared."""

    cfg: SceneConfig
    """The resolved config (a captured scene's fit, grid and loads filled in)."""
    gaussians: GaussianSet
    """The simulated Gaussians, on `device`."""
    background: Optional[GaussianSet]
    """Static Gaussians outside the simulated region (a capture), or None."""
    device: str
    """The device of this process's variants."""
    out_dir: Path
    """The run's output folder."""
    variants: tuple[str, ...]
    """The variants in the order asked for: the comparison's panels from left to right."""
    order: tuple[str, ...]
    """The order they run in: one with an event provider first (the leader), `baseline` last."""
    export: Optional[Export] = None
    """Splat-file export of the frames, or None."""
    view: Optional[Path] = None
    """The run's view record folder (`viewer.record`: what `fracture-gs view` shows), which each variant's frames
    are appended to, or None (not recorded)."""
    frames_png: bool = True
    """Write each comparison frame as frames/compare_NNNN.png too (`render-sim --frames-png`)."""


@dataclass
class ScheduleResult:
    """What a scheduler hands back: per variant its frames and summary, the leader's topology history."""

    frames: dict[str, list[np.ndarray]]
    """Each variant's rendered frames (H×W×3 uint8), in frame order."""
    summaries: dict[str, VariantSummary]
    """Each variant's summary; a variant not run has none."""
    topology: Optional[list[Topology]]
    """The leader's topology history (None: nothing latched)."""
    interrupted: bool
    """Whether Ctrl-C or a stop ended it early."""
    live: Optional[ComparisonVideo] = None
    """The comparison video composed beside the variants, or None (composed by the job afterwards)."""
