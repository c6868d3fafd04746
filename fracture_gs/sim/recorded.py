"""Per-frame torch (and Warp) work on fixed-shape device tensors, recorded once as a CUDA graph and
replayed after (docs/DESIGN.md "Performance rules"): a frame's diagnostics or particle queries are
tens of small launches whose host cost, not their GPU time, is what the run pays.

`Recorded(device)(key, fn)` returns fn()'s tensor: on CUDA from a graph recorded the first time `key`
is seen (the most recent `keep` keys are kept), on the CPU by calling fn. The key must name everything
the recording bakes in: buffer addresses, shapes, values chosen on the host. Inside fn nothing may read
back to the host or copy from host memory (build constants once per device). The capture is
thread-local (the render worker keeps allocating meanwhile), holds off the profiler's syncs and takes
`runtime.capture_lock` (torch's capture begins with a device-wide sync).
"""

from __future__ import annotations

from typing import Callable, Hashable

import torch

from ..profiling import phases
from ..runtime import capture_lock, ensure_warp, side_stream, warp_stream


class Recorded:
    def __init__(self, device, keep: int = 8):
        self.device, self.keep = str(device), keep
        self.graphs: dict = {}  # key → (graph, output), most recently used last

    @property
    def records(self) -> bool:
        return self.device.startswith("cuda")

    def __call__(self, key: Hashable, fn: Callable[[], torch.Tensor]) -> torch.Tensor:
        if not self.records:
            return fn()
        hit = self.graphs.pop(key, None)
        if hit is None:
            fn()  # warm-up outside the capture: lazy module loads, the allocator's and cuBLAS's caches
            ensure_warp()
            stream = side_stream(self.device, "record")  # one reused stream: each stream holds a cuBLAS workspace
            with torch.cuda.stream(stream):
                warp_stream(self.device)  # Warp's wrapper of the capture stream, made before capturing
            graph = torch.cuda.CUDAGraph()
            with capture_lock, phases.capturing():
                with torch.cuda.graph(graph, stream=stream, capture_error_mode="thread_local"):
                    out = fn()
            hit = (graph, out)
            while len(self.graphs) >= self.keep:
                self.graphs.pop(next(iter(self.graphs)))
        self.graphs[key] = hit
        hit[0].replay()
        return hit[1]
