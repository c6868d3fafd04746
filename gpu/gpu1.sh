set -uo pipefail
source .devpack/b/install.sh || exit 1
export PYTHONUNBUFFERED=1 PYTHONPATH=$PWD${PYTHONPATH:+:$PYTHONPATH}
nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv,noheader
python3 -c "import torch, warp, gsplat; print('torch', torch.__version__, 'warp', warp.config.version, 'gsplat', gsplat.__version__)"
s=$(date +%s)
timeout 200 python3 -m pytest -q -x -p no:cacheprovider --device cuda tests/test_fracturefields.py tests/test_sim_kernels.py tests/test_sim_physics.py -k "not stiff" > $OUT/pytest_cuda.log 2>&1; echo "pytest rc=$? $(( $(date +%s)-s ))s: $(tail -1 $OUT/pytest_cuda.log)"
grep -E "FAILED|Error|assert" $OUT/pytest_cuda.log | head -15
s=$(date +%s); timeout 120 python3 gpu/check_graphs.py 30 2>&1 | grep -v "^Module"; echo "graphs $(( $(date +%s)-s ))s"
s=$(date +%s); timeout 150 python3 apps/bench_fragments.py --device cuda:0 > $OUT/kbench.log 2>&1; echo "kbench rc=$? $(( $(date +%s)-s ))s"; tail -8 $OUT/kbench.log
s=$(date +%s); timeout 90 python3 apps/bench_diff.py --device cuda:0 --repeats 3 > $OUT/diff.log 2>&1; echo "diff rc=$? $(( $(date +%s)-s ))s"; grep -v "^Module" $OUT/diff.log | tail -14
