#!/usr/bin/env bash
# Table 2 before and after a change, on one card in one run: `fracture-gs bench` of an older package tree
# (a folder holding `fracture_gs/`, e.g. `git archive OLD fracture_gs | tar -x -C .oldtree`) and of this
# tree, interleaved round by round so both meet the same clocks and the same neighbours.
#   bash benchmarks/ab_table2.sh OLD_TREE ROUNDS [bench args ...]      # e.g. .oldtree 2 --device cuda:0
# Writes OUT/ab/{old,new}_R/bench.{md,json} (OUT defaults to runs/ab) and prints each run's Table 2 block.
set -euo pipefail
old=$(cd "$1" && pwd); rounds=$2; shift 2
root=$(pwd); out=${OUT:-$root/runs}/ab
for r in $(seq 1 "$rounds"); do
  for side in old new; do
    dir=$out/${side}_$r; mkdir -p "$dir"
    tree=$root; [[ $side == old ]] && tree=$old
    t0=$(date +%s.%N)
    (cd "$tree" && python -m fracture_gs.cli bench "$@" --out "$dir") > "$dir/log.txt" 2>&1 || { tail -20 "$dir/log.txt"; exit 1; }
    t1=$(date +%s.%N)
    echo "== $side round $r: $(python -c "print(f'{$t1 - $t0:.1f}')") s as a process"
  done
done
python - "$out" <<'PY'
import json, sys, pathlib
out = pathlib.Path(sys.argv[1])
for d in sorted(out.iterdir()):
    b = json.loads((d / "bench.json").read_text())
    rows = b.get("rows") or b.get("branches") or []
    print(d.name, json.dumps(rows)[:1500] if rows else sorted(b)[:20])
PY
