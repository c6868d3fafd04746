"""The dense grid and the slot storage of fragment fields (`sim.grid_storage = "slots"`; one dense field before a
latch whatever the storage): the layout (`layout.py`), the buffers (`fields.py`), the grid's extent (`domain.py`), the
transfer kernels (`kernels.py`, with P2G in runs, the fan-out and the mass-gradient normals beside them), the per-frame
field sums, and the host side of a substep (`slots.py`). Nothing here imports `sim.boxes`."""
