# Real captures on the lent GPU: the CUDA tests of this issue's code, then each capture as a user runs it
# (`render-sim FILE --device cuda:0 --frames 120`, 1280x720 panels by default), cold and warm, timed from the
# shell with the peak GPU memory (nvidia-smi), an export on the GPU, and Table 2's substep timings.
# Needs .devpack (warp, gsplat), .whl (gsply, zstandard, isal, imageio-ffmpeg) and .caps (the full captures).
set -uo pipefail
source .devpack/b/install.sh || exit 1
python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site .whl/*.whl \
  || exit 1
export PYTHONUNBUFFERED=1 PYTHONPATH=$PWD:/tmp/site${PYTHONPATH:+:$PYTHONPATH}
nvidia-smi --query-gpu=name,memory.total --format=csv,noheader
timeout 300 python3 -m pytest -q -p no:cacheprovider tests/test_energy.py tests/test_sphere_boundary.py \
  tests/test_capture_sampling.py tests/test_formats.py tests/test_capture_quality.py -m "not slow" --device cuda \
  2>&1 | tail -4
peak() { sort -n "$1" | tail -1; }
for f in .caps/biker.spz .caps/luma-seal.splat tests/data/captures/guitar.compressed.ply; do
  n=$(basename "$f")
  for pass in cold warm; do
    nvidia-smi --query-gpu=memory.used --format=csv,noheader,nounits -lms 100 > "/tmp/mem_${n}_$pass" &
    smi=$!
    s=$(date +%s.%N)
    timeout 280 python3 -m fracture_gs.cli render-sim "$f" --device cuda:0 --frames 120 --out "/tmp/r_$n" --profile \
      > "$OUT/log_${n}_$pass.txt" 2>&1
    rc=$?
    e=$(date +%s.%N)
    kill $smi
    echo "$n $pass rc=$rc wall=$(python3 -c "print(round($e-$s,1))")s peak_mem=$(peak "/tmp/mem_${n}_$pass")MiB"
  done
  grep -E "^\| (full|baseline|stress_zero) " "$OUT/log_${n}_warm.txt" | cut -c1-150
  grep -E "resolution:|particles:|load " "$OUT/log_${n}_warm.txt" | cut -c1-220
  python3 -c "
import imageio.v2 as iio
from fracture_gs.capture.quality import edge_strength
r = iio.get_reader('/tmp/r_$n/full.mp4')
first = r.get_data(0)
for last in r:
    pass
print('$n full edge last/first', round(edge_strength(last) / edge_strength(first), 3), first.shape)
iio.imwrite('$OUT/${n}_last.png', last)
"
done
timeout 200 python3 -m fracture_gs.cli render-sim .caps/biker.spz --device cuda:0 --frames 4 --export-ply 2 \
  --variants full --out /tmp/r_export > "$OUT/log_export.txt" 2>&1; echo "export on GPU rc=$? $(ls /tmp/r_export/ply/full)"
timeout 200 python3 benchmarks/memory.py .caps/biker.spz 40 2>&1 | grep -E "^peak|torch peak|MiB"
timeout 240 python3 -m fracture_gs.cli bench --device cuda:0 --placements 2 --trials 3 2>&1 | grep -v "^Module" | tail -12
