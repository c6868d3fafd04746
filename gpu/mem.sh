# GPU memory of a captured scene: the CLI's run with nvidia-smi's peak (expandable segments on by the CLI), then
# gpu/mem.py's breakdown of where torch's peak allocation comes from.
set -uo pipefail
source .devpack/b/install.sh || exit 1
python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site .whl/*.whl \
  || exit 1
export PYTHONUNBUFFERED=1 PYTHONPATH=$PWD:/tmp/site${PYTHONPATH:+:$PYTHONPATH}
for pass in cold warm; do
  nvidia-smi --query-gpu=memory.used --format=csv,noheader,nounits -lms 100 > /tmp/mem_$pass &
  smi=$!
  s=$(date +%s.%N)
  python3 -m fracture_gs.cli render-sim .caps/biker.spz --device cuda:0 --frames 120 --out /tmp/r_b > /tmp/log_$pass 2>&1
  rc=$?
  e=$(date +%s.%N)
  kill $smi
  echo "biker $pass rc=$rc wall=$(python3 -c "print(round($e-$s,1))")s peak_mem=$(sort -n /tmp/mem_$pass | tail -1)MiB"
done
timeout 200 python3 gpu/mem.py .caps/biker.spz 40 2>&1 | grep -E "^peak|torch peak|MiB|rasterization" | head -20
