"""The per-fragment boxes (`sim.grid_storage = "boxes"`, or `auto`): a dense box per fragment, its kernels
(`kernels.py`) and its host side (`fragment_boxes.py`). It shares the stencil math (`sim/stencil.py`) and the laws
(`sim/physics/`) with the slot storage and never imports `sim.grid` (tests/test_sim_tree.py)."""
