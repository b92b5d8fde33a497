#!/usr/bin/env bash
# End-to-end timing of the default Cornell box bake (the README's command), per stage, from
# the run's own --report. Usage: tools/bench_cornell.sh [RUNS] [extra bake options...]
set -euo pipefail
cd "$(dirname "$0")/.."
runs="${1:-3}"; shift || true
cargo build --release --quiet
out="$(mktemp -d)"
for i in $(seq 1 "$runs"); do
  ./target/release/radiosity bake meshes/cornell_box.obj -o "$out/cornell.ply" --report "$out/r$i.json" -q "$@"
done
python3 - "$out" "$runs" <<'PY'
import json, sys, statistics
out, runs = sys.argv[1], int(sys.argv[2])
reps = [json.load(open(f"{out}/r{i}.json")) for i in range(1, runs + 1)]
stages = ["load", "patches", "bvh", "form_factors", "solve", "bake", "gather", "write"]
r = reps[0]
print(f"patches {r['patches']}, vertices {r['vertices']}, rays {r['form_factors']['rays_cast']:,}, "
      f"nnz {r['form_factors']['nnz']:,}, iterations {r['iterations']}, residual {r['residual']:.2e}")
print("| stage | median s | min s | max s |\n|---|---|---|---|")
for s in stages + ["total"]:
    v = [sum(x["seconds"].values()) if s == "total" else x["seconds"][s] for x in reps]
    print(f"| {s} | {statistics.median(v):.3f} | {min(v):.3f} | {max(v):.3f} |")
PY
