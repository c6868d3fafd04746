#!/usr/bin/env bash
# What `--profile` adds to the warm GPU main job (issue 36): its phase timer synchronises the device at every
# section boundary, so a profiled run's in-run figure may be longer than an unprofiled run. RUNS interleaved
# pairs of `render-sim bread --preset paper`, plain and with --profile, each timed as a process; the profiled
# run's in-run wall and start-up rows; then the plain runs' in-run estimate (process minus the profiled runs'
# start-up before the run: the "imports" row).
# Usage (repository root, Warp and gsplat warm, e.g. after `fracture-gs info --warm-up`):
#   bash benchmarks/profile_overhead.sh [RUNS] [DEVICE]
set -uo pipefail
runs=${1:-3}; dev=${2:-cuda:0}
now() { date +%s.%N; }
one() {  # label, extra flags...
  local label=$1; shift; local t0 t1; t0=$(now)
  python -m fracture_gs.cli render-sim bread --preset paper --device "$dev" --out "/tmp/po_$label" "$@" \
    > "/tmp/po_$label.log" 2>&1 || echo "rc $? ($label)"
  t1=$(now); python -c "print(f'{$t1 - $t0:.2f}')"
}
plain=(); prof=(); inrun=(); imports=()
one warm > /dev/null
for i in $(seq 1 "$runs"); do
  plain+=("$(one "plain$i")")
  prof+=("$(one "prof$i" --profile)")
  inrun+=("$(grep -o '^wall time [0-9.]*' "/tmp/po_prof$i/profile.md" | awk '{print $3}')")
  imports+=("$(grep -E '^\| imports ' "/tmp/po_prof$i/profile.md" | awk -F'|' '{print $3}' | tr -d ' ')")
done
echo "| run | plain process s | profiled process s | profiled in-run s | start-up before the run s |"
echo "|---|---:|---:|---:|---:|"
for i in $(seq 0 $((runs - 1))); do
  echo "| $((i + 1)) | ${plain[$i]} | ${prof[$i]} | ${inrun[$i]} | ${imports[$i]} |"
done
python - "${plain[*]}" "${prof[*]}" "${inrun[*]}" "${imports[*]}" <<'PY'
import statistics as st, sys
plain, prof, inrun, imports = ([float(x) for x in a.split()] for a in sys.argv[1:5])
m = st.mean
print(f"means: plain {m(plain):.2f} s, profiled {m(prof):.2f} s as a process; profiled in-run {m(inrun):.2f} s; "
      f"plain in-run about {m(plain) - (m(prof) - m(inrun)):.2f} s (plain process minus the profiled run's time outside its wall)")
PY
sed -n '1,40p' /tmp/po_prof1/profile.md
