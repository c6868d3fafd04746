#!/usr/bin/env bash
# What a machine prepared ahead of use gets (issue 36 item 4): `fracture-gs info --warm-up`, then the bread paper
# preset RUNS times as processes, with gsplat's build folder read before and after each run. A first run much slower
# than the later ones, with new entries in the build's .ninja_log, means the run rebuilt what the warm-up had built
# (torch's JIT rebuilds when a compile command changes, e.g. another TORCH_CUDA_ARCH_LIST). Run it in ONE shell, so
# the warm-up and the runs see one environment; pass SKIP_WARM_UP=1 when the warm-up already ran in this shell.
# Usage (repository root, torch with CUDA, Warp, gsplat and imageio-ffmpeg importable):
#   bash benchmarks/warm_up_then_run.sh [RUNS] [DEVICE]
set -uo pipefail
runs=${1:-2}; dev=${2:-cuda:0}
echo "TORCH_CUDA_ARCH_LIST=${TORCH_CUDA_ARCH_LIST-<unset>} TORCH_EXTENSIONS_DIR=${TORCH_EXTENSIONS_DIR-<unset>}"
build=$(python -c "from fracture_gs.render.warm_up import torch_build_directory as d; print(d('gsplat_cuda'))")
entries() { if [[ -f $build/.ninja_log ]]; then grep -vc "^#" "$build/.ninja_log" || true; else echo 0; fi; }
if [[ -z ${SKIP_WARM_UP:-} ]]; then
  t0=$(date +%s.%N)
  python -m fracture_gs.cli info --warm-up --device "$dev" 2>&1 | grep -E "gsplat|warm-up done"
  echo "warm-up: $(python -c "print(f'{$(date +%s.%N) - $t0:.1f}')") s"
fi
echo "| run | process s | in-run s | render busy s | build log entries before → after |"
echo "|---|---:|---:|---:|---|"
for i in $(seq 1 "$runs"); do
  before=$(entries); t0=$(date +%s.%N)
  python -m fracture_gs.cli render-sim bread --preset paper --device "$dev" --out "/tmp/wur_$i" --profile \
    > "/tmp/wur_$i.log" 2>&1
  rc=$?; t1=$(date +%s.%N)
  w=$(grep -o "^wall time [0-9.]*" "/tmp/wur_$i/profile.md" 2>/dev/null | awk '{print $3}')
  r=$(grep -E "^\| render " "/tmp/wur_$i/profile.md" 2>/dev/null | awk -F'|' '{print $3}' | tr -d ' ')
  echo "| $i (rc $rc) | $(python -c "print(f'{$t1 - $t0:.1f}')") | $w | $r | $before → $(entries) |"
done
grep -ih "gsplat" /tmp/wur_1.log | head -3
