#!/usr/bin/env bash
# The warm GPU main job sampled by py-spy (issue 36): which Python code holds the interpreter lock (`--gil`), and
# what every thread does, waits included (`--idle`), summarised per thread by benchmarks/spy_summary.py.
# Usage (repository root, Warp and gsplat built, py-spy on PATH or in .spy/): bash benchmarks/gpu_spy.sh [DEVICE]
set -uo pipefail
dev=${1:-cuda:0}; spy=$(command -v py-spy || echo .spy/py-spy); rate=250
# SPY_FLAGS: the job's extra flags (default --profile; SPY_FLAGS= samples an unprofiled run). SPY_KEEP=DIR keeps
# the raw samples there.
read -ra extra <<< "${SPY_FLAGS---profile}"
job=(python -m fracture_gs.cli render-sim bread --preset paper --device "$dev" --schedule in-turn "${extra[@]}")
"${job[@]}" --out /tmp/spy_plain > /tmp/spy_plain.log 2>&1 && { grep "^wall time" /tmp/spy_plain/profile.md 2>/dev/null; true; }
for mode in gil idle; do
  flag=(--gil); [[ $mode == idle ]] && flag=(--idle)
  "$spy" record --threads "${flag[@]}" -r $rate --nonblocking --format raw -o "/tmp/spy_$mode.txt" -- \
    "${job[@]}" --out "/tmp/spy_$mode" > "/tmp/spy_$mode.log" 2>&1
  echo "== $mode: $(grep "^wall time" /tmp/spy_$mode/profile.md 2>/dev/null)"; [[ -n ${SPY_KEEP:-} ]] && cp "/tmp/spy_$mode.txt" "$SPY_KEEP/"
  python benchmarks/spy_summary.py "/tmp/spy_$mode.txt" --rate $rate --top 22 --only fracture_gs
done
