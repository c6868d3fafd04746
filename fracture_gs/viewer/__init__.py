"""`fracture-gs view`: a run's simulated Gaussians in the browser (DESIGN.md "The viewer").

`record` writes a run's view record as render-sim draws its frames (`format` is its layout), `store` reads it
back frame by frame, `panels` turns a frame into the browser's splat buffer, and `server` serves the page through
viser (imported only there, so a run records its frames without viser installed).
"""
