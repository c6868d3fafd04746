"""Sweeps: a grid of independent runs from one TOML spec, spread over the ranks of a torchrun launch.

    fracture-gs sweep accuracy                                   # 1 process (built-in spec)
    torchrun --nproc-per-node 2 -m fracture_gs.cli sweep accuracy --device cuda   # 2 GPUs

Modules (importing this package loads `spec` and `expansion` only and starts nothing: no process group,
no CUDA context, no Warp):

* `spec` — parse and check a spec (ConfigError with one sentence naming file, key, value, fix).
* `expansion` — the spec's ordered cells, with stable ids (a short hash of each cell's canonical
  parameters) and, for scene cells, resolved and validated configs.
* `cells` — run one cell: an accuracy setting (`fracture_gs.paper.accuracy`) or a scene config ×
  variant × settings (the simulation of render-sim, rendering off by default) → flat metrics.
* `cache` — OUT/cells/<id>.json, written atomically; a rerun skips what is there.
* `distributed` — torchrun's environment, one device per rank, the process group (nccl on GPUs,
  gloo on CPUs), rank 0's plan and gather over the group's store, heartbeats naming a dead rank.
* `driver` — `run_sweep`: plan, run, cache, gather, write.
* `report` — sweep.md/.tex/.csv/.json and sweep_pareto.png.

Built-in specs live in the package's configs/sweeps/ (`fracture-gs sweep accuracy` or
`configs/sweeps/accuracy.toml` from a checkout); docs/scaling.md covers launches on 1 GPU, N GPUs
and M machines, resuming, failures, and the plan for one scene larger than a GPU.
"""

from .expansion import Cell, expand
from .spec import SPEC_DIR, SweepSpec, builtin_specs, find_spec, load_spec

__all__ = ["SPEC_DIR", "Cell", "SweepSpec", "builtin_specs", "expand", "find_spec", "load_spec"]
