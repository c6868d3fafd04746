"""Speed against error: the same as `fracture-gs bench --accuracy` (flags alike).

python apps/accuracy.py --quick                      # CPU, a few minutes
python apps/accuracy.py --device cuda:0 --out runs/accuracy_gpu
"""

import sys

from fracture_gs.cli import main

if __name__ == "__main__":
    sys.exit(main(["bench", "--accuracy", *sys.argv[1:]]))
