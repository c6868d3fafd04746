#!/usr/bin/env bash
# The README's CPU main job of two trees, interleaved (issue 36): OLD (a folder holding an older `fracture_gs`, e.g.
# from `git archive <commit> fracture_gs | tar -x -C .oldtree`) against this tree, one warm-up each (Warp compiles
# what changed), then RUNS pairs, each a process timed from the shell (wall, user+sys CPU seconds). Then whether the
# two trees wrote the same bytes (`same_outputs.py`): a speed-up must change no number.
# Usage (repository root, the package's dependencies importable):
#   bash benchmarks/ab_cpu_job.sh .oldtree [RUNS] [SCENE]
set -uo pipefail
old=$(cd "${1:?give the folder of the older tree}" && pwd); runs=${2:-3}; scene=${3:-bread}; here=$PWD
py=$(command -v python)
one() {  # label, dir
  cd "$2"
  /usr/bin/time -f "%e %U %S" -o "/tmp/ab_cpu_$1.time" "$py" -m fracture_gs.cli render-sim "$scene" --device cpu \
    --out "/tmp/ab_cpu_$1" > "/tmp/ab_cpu_$1.log" 2>&1
  local rc=$?; cd "$here"
  read -r wall user sys < <(tail -1 "/tmp/ab_cpu_$1.time")
  echo "| $1 | $wall | $(python -c "print(f'{$user + $sys:.1f}')") | $(cut -d' ' -f1 /proc/loadavg) | $rc |"
}
echo "| run | process s | user+sys s | load | rc |"
echo "|---|---:|---:|---:|---:|"
one warm_new "$here"; one warm_old "$old"
for i in $(seq 1 "$runs"); do one "new$i" "$here"; one "old$i" "$old"; done
python benchmarks/same_outputs.py /tmp/ab_cpu_old1 /tmp/ab_cpu_new1
