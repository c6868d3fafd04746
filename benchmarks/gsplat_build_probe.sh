#!/usr/bin/env bash
# Short GPU runs in a row while gsplat has never been built (issue 36, `warm_up.EarlierBuild`): the first run starts
# gsplat's detached build; every later run that starts while it runs must wait for that build, not start another
# into torch's one build folder. Uses a fresh TORCH_EXTENSIONS_DIR, so any machine is "fresh" for gsplat.
# Prints, per run: process seconds, how many build processes ran at its end, what its log says of gsplat; then how
# long the build took after the last run, whether the build is cached, and whether a run after it drew with gsplat.
# Usage (repository root, torch with CUDA, Warp, gsplat and imageio-ffmpeg importable):
#   bash benchmarks/gsplat_build_probe.sh [RUNS] [DEVICE]
set -uo pipefail
runs=${1:-4}; dev=${2:-cuda:0}
export TORCH_EXTENSIONS_DIR=${TORCH_EXTENSIONS_DIR:-/tmp/fgs_probe_ext_$$}
rm -rf "$TORCH_EXTENSIONS_DIR"
log=$(python -c "from fracture_gs.render.warm_up import build_log; print(build_log())")
rm -f "$log" "${log%.log}.pid"
builders() { pgrep -fc "from gsplat.cuda import _backend" || true; }
cached() { python -c 'import sys; from fracture_gs.render.warm_up import gsplat_needs_compile as n; sys.exit(1 if n() else 0)'; }
echo "| run | process s | build processes at its end | what it says of gsplat |"
echo "|---|---:|---:|---|"
for i in $(seq 1 "$runs") after; do
  t0=$(date +%s.%N)
  python -m fracture_gs.cli render-sim bread --preset paper --frames 5 --device "$dev" --out "/tmp/probe_$i" \
    > "/tmp/probe_$i.log" 2>&1
  rc=$?; t1=$(date +%s.%N)
  said=$(grep -io "still building[^;]*\|waiting for[^.]*\|torch rasterizer[^.]*\|gsplat[^.]*failed[^.]*" \
    "/tmp/probe_$i.log" | head -2 | tr '\n' ' ')
  echo "| $i (rc $rc) | $(python -c "print(f'{$t1 - $t0:.1f}')") | $(builders) | ${said:-nothing} |"
  if [[ $i == "$runs" ]]; then  # wait for the build, then one more run
    tw=$(date +%s)
    until cached; do sleep 2; (( $(date +%s) - tw > 300 )) && break; done
    echo "| (build) | done $(( $(date +%s) - tw )) s after run $runs; cached: $(cached && echo yes || echo no) | $(builders) | |"
  fi
done
echo
echo "log tail: $(tail -2 "$log" 2>/dev/null | tr '\n' ' ')"
echo "ninja stops in the log: $(grep -c "ninja: build stopped" "$log" 2>/dev/null || true)"
