#!/usr/bin/env bash
# One device call: solver tests on CUDA, the Table 2 / baseline benchmark, the renderer PSNR check.
# Run from the repository root on the GPU machine after `source .devpack/b/install.sh`.
set -uo pipefail
export PYTHONUNBUFFERED=1 PYTHONPATH=$PWD${PYTHONPATH:+:$PYTHONPATH}
OUT=${OUT:-/tmp/gpu_out}; mkdir -p "$OUT"
nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv,noheader | tee "$OUT/gpu.txt"
python3 -c "import torch, warp, gsplat; print('torch', torch.__version__, 'warp', warp.config.version, 'gsplat', gsplat.__version__)" | tee -a "$OUT/gpu.txt"
start=$(date +%s)
python3 -m pytest -q -p no:cacheprovider --device cuda tests/test_sim_kernels.py tests/test_sim_physics.py \
  tests/test_fracturefields.py tests/test_providers.py > "$OUT/pytest_cuda.log" 2>&1
echo "pytest rc=$? ($(( $(date +%s) - start )) s): $(tail -1 "$OUT/pytest_cuda.log")"
fracture-gs bench --device cuda:0 --out "$OUT/bench" > "$OUT/bench.log" 2>&1; echo "bench rc=$?"
python3 benchmarks/check_render_gpu.py > "$OUT/render.log" 2>&1; echo "render rc=$?"
tail -25 "$OUT/bench.log"; tail -15 "$OUT/render.log"; grep -E "FAILED|Error" "$OUT/pytest_cuda.log" | head -20
