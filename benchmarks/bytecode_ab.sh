#!/usr/bin/env bash
# What missing Python bytecode costs the warm GPU main job (issue 36), before and after `info --warm-up` writes it.
# The lent GPU hosts set PYTHONDONTWRITEBYTECODE=1 and ship torch and numpy without bytecode, so every process
# compiles their sources again; `info` reports that and `info --warm-up` compiles them once.
# Run it on a machine whose Warp kernels and gsplat build are warm but whose bytecode is as installed (e.g. after
# an older tree's `info --warm-up`, which had no bytecode step). In one call:
#   1. `info`'s bytecode row; `import torch` twice; RUNS warm runs of the bread paper preset (process and in-run);
#   2. `info --warm-up` (writes the bytecode; the kernels come from the cache);
#   3. the same again; then how far the metrics of a run before and after differ, next to two runs before.
# Usage (repository root, torch with CUDA, Warp, gsplat and imageio-ffmpeg importable):
#   bash benchmarks/bytecode_ab.sh [RUNS] [DEVICE]
set -uo pipefail
runs=${1:-3}; dev=${2:-cuda:0}
now() { date +%s.%N; }
secs() { python -c "print(f'{$2 - $1:.2f}')"; }
fgs() { python -m fracture_gs.cli "$@"; }
imports() {  # label
  for i in 1 2; do
    local t0 t1; t0=$(now); python -c "import torch; torch.zeros(1, device='$dev')"; t1=$(now)
    echo "| $1 | import torch + one CUDA op | $(secs "$t0" "$t1") | |"
  done
}
job() {  # label
  local t0 t1 w; t0=$(now)
  fgs render-sim bread --preset paper --device "$dev" --out "/tmp/bc_$1" --profile > "/tmp/bc_$1.log" 2>&1 || echo "rc $? ($1)"
  t1=$(now); w=$(grep -o "^wall time [0-9.]*" "/tmp/bc_$1/profile.md" | awk '{print $3}')
  echo "| ${1%%[0-9]*} | render-sim bread --preset paper | $(secs "$t0" "$t1") | $w |"
}
echo "before: $(fgs info | grep '^bytecode')"
echo
echo "| bytecode | what | process s | in-run s |"
echo "|---|---|---:|---:|"
imports "as installed"
for i in $(seq 1 "$runs"); do job "before$i"; done
fgs info --warm-up --device "$dev" > /tmp/bc_warm_up.log 2>&1 || echo "warm-up failed: $(tail -3 /tmp/bc_warm_up.log)"
imports "written"
for i in $(seq 1 "$runs"); do job "after$i"; done
echo
grep -E "Python bytecode|warm-up done" /tmp/bc_warm_up.log
echo "after: $(fgs info | grep '^bytecode')"
python benchmarks/metrics_gap.py /tmp/bc_after1 /tmp/bc_before1
[[ $runs -ge 2 ]] && python benchmarks/metrics_gap.py /tmp/bc_before2 /tmp/bc_before1
