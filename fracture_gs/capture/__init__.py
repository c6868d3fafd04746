"""Your own captured scene: a splat file (3DGS or compressed PLY, .splat, .spz) → a cleaned, fitted, filled
object with a material, a resolution, a load and a camera (`resolve`), and simulated frames back to splat
files in the scene's frame (`export`).

Modules: `clean` (broken Gaussians, floaters, outliers), `ground` (the layer the object stands on, kept
static), `fit` (cameras.json, up axis, region of interest, the similarity transform), `transform` (moving
Gaussians and their SH), `materials` (stiff brittle presets, material regions), `resolution` (Δx from the
object's thin parts within a device budget), `sample` (particles that follow the grid, carrying every
Gaussian), `loads` (pull, drop, impact, shoot, crush, auto), `camera` (framing), `scene` (`resolve`),
`quality` (edge strength, pieces: the measures of the targets), `starter` (the commented TOML of
`fracture-gs init`), `export` (`--export-ply`).
"""
