#!/usr/bin/env bash
# Mutation testing on the lent machine's many cores (mutation/run.py). Phases, chained in warm calls:
#   bash mutation/device.sh setup            # install the carried wheels, check imports
#   bash mutation/device.sh map              # coverage map (one context per test) + durations
#   bash mutation/device.sh run ARGS...      # mutation/run.py run ARGS (e.g. --workers 60 --sample 15 --budget 480)
# Results land in $OUT: report.txt, survivors.json, durations.txt.
set -uo pipefail
source .devpack/b/install.sh || exit 1
SITE=/tmp/mutsite
if [[ ! -f $SITE/.done ]]; then
  pip install -q --no-deps --target $SITE .whl/mut/*.whl .whl/*.whl >/dev/null 2>&1 && touch $SITE/.done
fi
export PYTHONPATH=$SITE:$PYTHONPATH OMP_NUM_THREADS=1 MKL_NUM_THREADS=1
phase=$1; shift
case $phase in
  setup)
    python -c "import warp, gsplat, cosmic_ray, pytest_cov, hypothesis, imageio_ffmpeg, gsply, fracture_gs; print('imports ok')"
    python -c "import matplotlib, scipy, cv2, tqdm, imageio; print('extras ok')"
    nproc; free -g | head -2 ;;
  map)
    python mutation/run.py map --jobs "${1:-56}"
    grep -h "s call\|s setup" mutation/.state/map.*.log | sort -rn | head -400 > "$OUT/durations.txt"
    tail -n 3 mutation/.state/map.*.log | grep -v "^$" > "$OUT/map_tail.txt" ;;
  run)  # a map made elsewhere travels gzipped (carry mutation/.state/coverage_map.json.gz and durations.json)
    [[ -f mutation/.state/coverage_map.json.gz ]] && gunzip -kf mutation/.state/coverage_map.json.gz
    python mutation/run.py run "$@"
    pkill -f pick_tests.py; pkill -f "pytest -x -q -p no:cacheprovider"
    cp mutation/.state/report.txt mutation/.state/survivors.json "$OUT/"
    gzip -c mutation/.state/session.sqlite > "$OUT/session.sqlite.gz" ;;
esac
