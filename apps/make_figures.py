"""Regenerate every table and figure of the paper: the same as `fracture-gs figures` (flags alike).

python apps/make_figures.py                          # CPU: quick protocol, a few minutes
python apps/make_figures.py --device cuda:0 --out figures/gpu   # GPU: paper protocol
"""

import sys

from fracture_gs.cli import main

if __name__ == "__main__":
    sys.exit(main(["figures", *sys.argv[1:]]))
