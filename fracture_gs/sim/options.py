"""`SimOptions`: how the solver launches its kernels, one frozen value per simulator (`Simulator.options`).

None of these changes what a substep computes: each picks which thread does what, or in which order the launches run,
and the fields agree to the order of float32 sums (bitwise on the CPU, where a single thread runs every launch in
order; tests/test_transfer_launch.py, tests/test_p2g_runs.py). Their defaults follow the device
(`SimOptions.for_device`: the GPU's remedies are off on the CPU, where they only cost). Change them by replacing the
value, `sim.options = dataclasses.replace(sim.options, fanout=True)`: a recorded CUDA graph whose launches change is
recorded again (`frames.FrameRunner.graph_key`).
"""

from __future__ import annotations

from dataclasses import dataclass

P2G_RUN = 8  # particles per P2G thread in cell order on a GPU: runs of 8 were the fastest on the Table 2 ficus (P2G
# under half its time one per thread); not while most particles take the slot path (slower there; BENCHMARKS.md)


@dataclass(frozen=True)
class SimOptions:
    """The launch switches of a `Simulator` (docs/DESIGN.md "Performance rules")."""

    use_graphs: bool = True
    """CUDA: record one substep as a CUDA graph and replay it for every substep of a frame (and the per-frame solo
    query as graphs, `recorded.Recorded`); ignored on the CPU."""
    concurrent: bool = True
    """CUDA: P2G's and the grid update's independent launches (the pool's reset, the fan-out, the pool pass; the box
    clear beside G2P) on a second stream, joined back (`runtime.StreamFork`); a no-op on the CPU."""
    fanout: bool = False
    """Slot storage after a latch: the particles that are not solo take one thread per stencil node in P2G and a warp
    of 32 in G2P (`grid/fanout_kernels.py`), so their 27 slot lookups do not run in a row after the dense bulk.
    On by default on a GPU."""
    g2p_fanout_max: float = 1.0 / 16
    """G2P fans out only while the particles that are not solo are at most this share of all particles [fraction]:
    when they are the bulk, per-particle threads already fill a GPU and the warp's shuffles only cost."""
    one_gather: bool = True
    """With the G2P fan-out: the solo particles are gathered in the fan-out's launch behind the listed ones (one
    launch), not in a launch of their own."""
    slow_first: bool = False
    """Slot storage after a latch: G2P launches the particles that are not solo first, so their slot lookups run
    under the dense bulk instead of finishing last. On by default on a GPU."""
    p2g_run: int = 0
    """P2G of the dense-path particles in runs of this many consecutive particles per thread, summed in registers
    while they share a stencil (`grid/run_kernels.py`; the boxes' P2G too) [particles]; 0: one particle per
    thread. On (P2G_RUN) by default for particles sorted by cell on a GPU (`sim.particle_order = "cell"`,
    `Simulator.sort_particles("cell")`)."""

    @classmethod
    def for_device(cls, device: str, particle_order: str = "scene") -> SimOptions:
        """The defaults for `device` ('cpu' or 'cuda:N') and particles in `particle_order` ("scene" or "cell"): the
        fan-out and the slow-first G2P on a GPU, P2G in runs on a GPU for particles sorted by cell."""
        cuda = device.startswith("cuda")
        run = P2G_RUN if particle_order == "cell" and device != "cpu" else 0
        return cls(fanout=cuda, slow_first=cuda, p2g_run=run)
