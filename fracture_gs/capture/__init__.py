"""Your own captured scene: a trainer's 3DGS PLY → a cleaned, fitted, filled object with a load and a
camera (`resolve`), and simulated frames back to standard 3DGS PLYs in the scene's frame (`export`).

Modules: `clean` (broken Gaussians, floaters, outliers), `fit` (cameras.json, up axis, region of
interest, the similarity transform), `transform` (moving Gaussians and their SH), `loads` (pull,
drop, impact), `camera` (framing), `scene` (`resolve`), `starter` (the commented TOML of
`fracture-gs init`), `export` (`--export-ply`).
"""
