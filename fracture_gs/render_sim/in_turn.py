"""The variants of a render-sim run one after the other on one device (the default schedule).

The leader (the first variant with an event provider) runs first; its latched topology history is saved to
topology.npz and replayed by every later variant at the same frames, so the comparison shows one fracture.
While the last variant runs, the comparison video is composed beside it (`ComparisonVideo.start_live`), once
every earlier variant has frames and the topology is known.
"""

from __future__ import annotations

from ..sim.topology import save_history
from .comparison import ComparisonVideo
from .context import RunContext, ScheduleResult
from .painter import Painter
from .variant import run_variant


def run_in_turn(ctx: RunContext, painter: Painter, metrics_file, stop=None) -> ScheduleResult:
    """Run `ctx.order` one variant at a time; `stop` (an Event) ends the run at the next frame, as Ctrl-C does."""
    order = ctx.order
    frames: dict = {}
    summaries: dict = {}
    topology, interrupted, live = None, False, None
    try:
        for k, variant in enumerate(order):
            if stop is not None and stop.is_set():
                interrupted = True
                break
            frames[variant] = []
            if k > 0 and k == len(order) - 1 and topology is not None and all(frames[v] for v in order[:k]):
                statuses = [summaries[v].status if v in summaries else "ok" for v in ctx.variants]
                panels = [frames[v] for v in ctx.variants]
                live = ComparisonVideo(ctx.cfg, ctx.variants, panels, topology, ctx.out_dir, statuses, ctx.frames_png)
                live.start_live(frames[variant])
            summaries[variant], topology = run_variant(
                ctx, variant, painter, metrics_file, frames[variant], topology, stop=stop
            )
            if topology is not None and not (ctx.out_dir / "topology.npz").exists():
                save_history(ctx.out_dir / "topology.npz", topology)
            if summaries[variant].interrupted:
                interrupted = True
                break
    except KeyboardInterrupt:  # between variants
        interrupted = True
    except BaseException:
        if live is not None:
            live.abort()
        raise
    return ScheduleResult(frames, summaries, topology, interrupted, live)
