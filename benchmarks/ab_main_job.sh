#!/usr/bin/env bash
# The GPU main job of two trees, interleaved in one call (issue 36): OLD (a folder holding an older `fracture_gs`,
# e.g. from `git archive <commit> fracture_gs | tar -x -C .oldtree`) against this tree, one warm-up each, then RUNS
# pairs, each a process with --profile. Prints a table (process and in-run wall, busy phases), then how far the
# metrics of the two trees differ next to how far two runs of one tree differ (GPU atomics are not deterministic).
# Usage (repository root, torch with CUDA, Warp, gsplat and imageio-ffmpeg importable):
#   bash benchmarks/ab_main_job.sh .oldtree [RUNS] [DEVICE]
set -uo pipefail
old=$(cd "${1:?give the folder of the older tree}" && pwd); runs=${2:-3}; dev=${3:-cuda:0}; here=$PWD
one() {  # label, dir
  cd "$2"; local t0; t0=$(date +%s.%N)
  python -m fracture_gs.cli render-sim bread --preset paper --device "$dev" --out "/tmp/ab_$1" --profile > "/tmp/ab_$1.log" 2>&1
  local rc=$? t1; t1=$(date +%s.%N); cd "$here"
  local w ph; w=$(grep -o "^wall time [0-9.]*" "/tmp/ab_$1/profile.md" | awk '{print $3}')
  ph=$(grep -E "^\| (simulate|diagnostics|render|compose|encode) " "/tmp/ab_$1/profile.md" | awk -F'|' '{printf "%s=%s ", $2, $3}' | tr -s ' ')
  echo "| $1 | $(python -c "print(f'{$t1 - $t0:.1f}')") | $w | $ph| $rc |"
}
echo "| run | process s | in-run s | phases busy s | rc |"
echo "|---|---:|---:|---|---:|"
one warm_new "$here"; one warm_old "$old"
for i in $(seq 1 "$runs"); do one "new$i" "$here"; one "old$i" "$old"; done
python benchmarks/metrics_gap.py /tmp/ab_new1 /tmp/ab_old1
python benchmarks/metrics_gap.py /tmp/ab_old2 /tmp/ab_old1
