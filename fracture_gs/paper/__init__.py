"""The paper's evidence, inside the package: `fracture-gs figures` and `fracture-gs bench`.

Modules (each imported on demand; importing this package imports none of them):

* `protocol` — the paper's protocol per scene and its two sizes, ``quick`` (CPU) and ``paper``.
* `experiments` — run an experiment config over its variants; the run cache.
* `tables` — one table definition written as Markdown, CSV and LaTeX.
* `paper_tables` — Tables 1–5 from experiment runs.
* `plots` — the teaser, multi-scene, method and curves figures.
* `readme` — a figures folder's README.
* `figures` — `run_figures`: every table and figure in one call.
* `bench` — Table 2 timings (transfer branches) and the baseline substep by phase.
* `accuracy` — speed against error on cases with known answers.
"""
