"""Transfer benchmarks (paper Table 2): the same as `fracture-gs bench` (flags alike).

python apps/bench.py --device cuda:0                 # full table at the paper's particle count
python apps/bench.py --device cpu --particles 20000  # a CPU smoke run
"""

import sys

from fracture_gs.cli import main

if __name__ == "__main__":
    sys.exit(main(["bench", *sys.argv[1:]]))
