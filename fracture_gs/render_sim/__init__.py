"""`fracture-gs render-sim`, the main job: simulate each variant, render it, write videos, metrics and a summary.

Outputs in the run's folder: <variant>.mp4, comparison.mp4 (side by side, captions, circular fracture insets),
frames/compare_NNNN.png (`--frames-png`; by default on the CPU only), metrics.jsonl, summary.json, summary.md,
topology.npz, config.toml. Ctrl-C or a divergence keeps every frame and metric already written.

The path of a run, top to bottom: `job.run_render_sim` prepares the scene (`pipeline.prepare_scene`) and
makes one frozen `context.RunContext`; a scheduler (`in_turn`, `threads` or `multi_device`) runs each variant
through `variant.run_variant` (the pipeline's frames, drawn by `painter.Painter` on a worker thread) and
returns one `context.ScheduleResult`; the job finishes the comparison video (`comparison`) and writes the
`summary.RunSummary`.
"""

from .context import Export, RunContext, ScheduleResult
from .job import run_render_sim
from .painter import Painter
from .summary import AfterLatch, PlaneContact, RunSummary, VariantSummary, summarize

__all__ = [
    "AfterLatch",
    "Export",
    "Painter",
    "PlaneContact",
    "RunContext",
    "RunSummary",
    "ScheduleResult",
    "VariantSummary",
    "run_render_sim",
    "summarize",
]
