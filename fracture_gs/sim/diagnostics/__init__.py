"""Per-frame diagnostics (docs/DESIGN.md "Diagnostics"): the tracker that writes metrics.jsonl's rows
(`tracker.py`), the metrics as device tensors (`metrics.py`), the energies (`energy.py`) and the fragment-aware
penetration (`penetration.py`, with its Warp launches in `overlap_kernels.py`)."""
