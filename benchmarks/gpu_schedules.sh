#!/usr/bin/env bash
# The GPU main job under each schedule of one device (issue 36): `render-sim bread --preset paper` in turn, in
# threads and in forked worker processes, interleaved RUNS times after one warm-up run (which also waits for
# gsplat's build), each a process with --profile. Prints a table: process wall, in-run wall, each variant's own
# wall (from its first frame), the busy phases; then how far the schedules' metrics differ next to how far two
# runs of one schedule differ (GPU atomics are not deterministic).
# PROFILE=0 runs them without --profile (its section syncs perturb the threads a little): the in-run and busy columns
# are then empty, and the process and variants' own walls remain.
# Usage (repository root, torch with CUDA, Warp, gsplat and imageio-ffmpeg importable):
#   [PROFILE=0] bash benchmarks/gpu_schedules.sh [RUNS] [DEVICE] [SCHEDULES]  (SCHEDULES default "in-turn processes threads")
set -uo pipefail
runs=${1:-3}; dev=${2:-cuda:0}; schedules=${3:-in-turn processes threads}
profile=(--profile); [[ ${PROFILE:-1} == 0 ]] && profile=()
if ! python -c "import imageio_ffmpeg" 2>/dev/null; then  # a lent machine may lack the video encoder: carry its wheel
  whl=$(ls .whl*/imageio_ffmpeg-*.whl 2>/dev/null | head -1)
  [[ -n $whl ]] || { echo "imageio-ffmpeg is missing: pip install imageio-ffmpeg (or carry its wheel in .whl/)"; exit 2; }
  pip install -q --no-deps --target /tmp/fgs_iio "$whl" && export PYTHONPATH=/tmp/fgs_iio${PYTHONPATH:+:$PYTHONPATH}
fi
one() {  # label, schedule
  local t0 t1 rc w ph vw
  t0=$(date +%s.%N)
  python -m fracture_gs.cli render-sim bread --preset paper --device "$dev" --schedule "$2" --out "/tmp/sch_$1" \
    "${profile[@]}" > "/tmp/sch_$1.log" 2>&1
  rc=$?; t1=$(date +%s.%N)
  w=$(grep -o "^wall time [0-9.]*" "/tmp/sch_$1/profile.md" 2>/dev/null | awk '{print $3}')
  ph=$(grep -E "^\| (simulate|diagnostics|render|compose|encode) " "/tmp/sch_$1/profile.md" 2>/dev/null |
    awk -F'|' '{printf "%s=%s ", $2, $3}' | tr -s ' ')
  vw=$(python -c "import json; s=json.load(open('/tmp/sch_$1/summary.json')); print(' '.join(f\"{v['variant']}={v.get('wall_s', 0):.2f}\" for v in s['variants']))" 2>/dev/null)
  echo "| $1 | $2 | $(python -c "print(f'{$t1 - $t0:.1f}')") | $w | $vw | $ph| $rc |"
  [[ $rc == 0 ]] || tail -5 "/tmp/sch_$1.log"
}
echo "# GPU schedules, $(date -u +%F) — $(nvidia-smi --query-gpu=name --format=csv,noheader | head -1), $(nproc) cores"
echo
echo "| run | schedule | process s | in-run s | variants' own wall s | phases busy s | rc |"
echo "|---|---|---:|---:|---|---|---:|"
one warm in-turn
t1=$(date +%s)
while python -c 'import sys; from fracture_gs.render.warm_up import gsplat_needs_compile as n; sys.exit(0 if n() else 1)'; do
  sleep 2; (( $(date +%s) - t1 > 240 )) && break
done
for i in $(seq 1 "$runs"); do
  for s in $schedules; do one "${s}_$i" "$s"; done
done
grep -h "processes\|spawning" /tmp/sch_processes_1.log 2>/dev/null | head -3
first=${schedules%% *}
for s in $schedules; do
  [[ $s == "$first" ]] || python benchmarks/metrics_gap.py "/tmp/sch_${s}_1" "/tmp/sch_${first}_1"
done
python benchmarks/metrics_gap.py "/tmp/sch_${first}_2" "/tmp/sch_${first}_1"
