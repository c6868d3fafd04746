set -uo pipefail
source .devpack/b/install.sh || exit 1
export PYTHONUNBUFFERED=1 PYTHONPATH=$PWD${PYTHONPATH:+:$PYTHONPATH}
s=$(date +%s); timeout 200 python3 apps/bench_fragments.py --device cuda:0 2>&1 | grep -v "^Module" | tail -7; echo "kbench $(( $(date +%s)-s ))s"
timeout 120 python3 gpu/check_graphs.py 30 2>&1 | grep -v "^Module"
python3 gpu/prof.py 2>&1 | grep -v "^Module" | head -22
