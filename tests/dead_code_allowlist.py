"""Names vulture reports as unused that are used all the same (read by `tests/test_dead_code.py`).

Each line names why: called by Python or a library rather than by our code, or public API that a
user reads (documented in README.md or the docstring) and the tests exercise. Anything else vulture
finds in `fracture_gs/`, `examples/` or `benchmarks/` is dead and is removed, not listed here.
"""

# ruff: noqa: F821, B018
# Called by Python or by a library, never by name.
__getattr__  # module-level lazy attributes (PEP 562): fracture_gs/__init__.py, fracture_gs/cli/__init__.py
__dir__  # module-level dir() with the lazy names (PEP 562)
_.debug  # the logger interface Warp's quiet logger must offer (cli/devices.py)
_._negative_number_matcher  # argparse reads it to tell "-64x48" from a flag (cli/parser.py)
_._num_to_string  # matplotlib's LogFormatter calls it (paper/accuracy.py)
corotated_kirchhoff_grad  # registered by @wp.func_grad as the adjoint Warp calls (sim/diff/kernels.py)
_.up_direction  # a viser camera property: assigning it moves the browser's camera (viewer/server.py)
_.showwarning  # the warnings module calls it per warning: benchmarks/overlap_probe.py counts torch's sync warnings
_.buffer  # a viser splat node property: assigning it sends the new splats to the browser (viewer/server.py)

# Public API a user reads, exercised by the tests.
_.last_simulator  # FractureSim / differentiable: the simulator of the last forward, to inspect
_.trimmed_count  # render.crack_faces: how many Gaussians the crack trim shrank (a diagnostic)
_.forks  # runtime.StreamFork: the forked streams, for callers that record graphs
_.clamped_count  # Simulator: particles whose F was clamped (a diagnostic)
write_video  # io.video: write frames to an mp4
read_video  # io.video: read an mp4 back as frames
polar_rotation_reference  # linalg: the float64 twin of the polar rotation kernel
singular_values_reference  # linalg: the float64 twin of the singular values kernel
encode_frame  # viewer.format: the numpy reference of the recorder's on-device frame encoder (tests hold them equal)
encode_epoch  # viewer.format: the numpy reference of the recorder's on-device epoch encoder
box_volume  # sim.grid.layout: node count of a box
fragment_overlap  # sim.diagnostics.penetration: the voxel measure of Panel A's overlap
collider_crossing  # sim.diagnostics.penetration: particles behind a collider plane
depth_from_share  # sim.diagnostics.penetration_kernels: the inversion alone, tested against closed form and twin
WALL_KEYS  # sweep.cells: the row keys that differ between runs by nature (wall times)
RUN_KEYS  # sweep.driver: the row keys that say where and when a cell ran

# Dataclass fields written to summary.json through dataclasses.asdict / fields (render_sim.summary).
_.plane_first_contact
_.plane_penetration
_.plane_max_vt_near
_.plane_max_vn_post
_.plane_momentum_residual
_.substeps_per_s
_.mixing_counterfactual_mean
_.mixing_counterfactual_max
_.mixing_realized_mean
_.mixing_realized_max
_.shared_support_pct_mean
_.mass_residual_max
_.separated
_.penetration_max
_.identity_crossing_max
_.fragment_crossing_max
_.fragment_penetration_max
_.collider_crossing_max
_.cp_momentum_residual
_.rel_normal_velocity_after
_.max_delta_vt
