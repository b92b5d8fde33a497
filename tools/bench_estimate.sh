#!/usr/bin/env bash
# The estimate `radiosity info` makes before a bake, against the bake itself: for each case,
# the estimated method, patches, peak memory and seconds, and the bake's patches, peak memory
# (the report's VmHWM) and wall seconds. Also the sky and the sun on a roofless hall of 10^5
# triangles. Prints a table (BENCHMARKS.md, "Defaults that scale"); about 2 minutes on 2 cores.
# Usage: bash tools/bench_estimate.sh
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release --quiet
R="$PWD/target/release/radiosity"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
cd "$work"
"$R" generate hall --triangles 10000 -o hall1e4.obj
"$R" generate hall --triangles 100000 -o hall1e5.obj
# The hall without its ceiling (the wall faces at the top): a courtyard the sky lights.
python3 - <<'PY'
lines = open("hall1e5.obj").read().split("\n")
vs = [tuple(map(float, l.split()[1:4])) for l in lines if l.startswith("v ")]
top = max(v[2] for v in vs)
out, cur = [], None
for l in lines:
    if l.startswith("usemtl"):
        cur = l.split()[1]
    if l.startswith("f ") and cur == "wall":
        idx = [int(x.split("/")[0]) - 1 for x in l.split()[1:]]
        if all(abs(vs[i][2] - top) < 1e-9 for i in idx):
            continue
    out.append(l)
open("court1e5.obj", "w").write("\n".join(out))
PY
box="$OLDPWD/meshes/cornell_box.obj"
cat > cases.txt <<CASES
cornell, defaults|$box|
cornell, --max-edge 110|$box|--max-edge 110
cornell, --max-edge 40 --method matrix --gather none|$box|--max-edge 40 --method matrix --gather none
cornell, --max-edge 30 --method matrix --refine 0 --gather none|$box|--max-edge 30 --method matrix --refine 0 --gather none
hall 10^4, defaults|hall1e4.obj|
hall 10^4, --epsilon 1e-5 --gather none|hall1e4.obj|--epsilon 1e-5 --gather none
hall 10^5, defaults|hall1e5.obj|
roofless hall 10^5, --up z --sky 1 --sun 135,40,500, lights off|court1e5.obj|--up z --sky 1 --sun 135,40,500 --emission light=0
CASES
echo "| case | method | patches (est.) | most patches (est.) | MiB (est.) | s (est.) | patches | peak MiB | s |"
echo "|---|---|---|---|---|---|---|---|---|"
while IFS='|' read -r name input opts; do
  # shellcheck disable=SC2086
  "$R" info "$input" --json $opts > est.json
  # shellcheck disable=SC2086
  /usr/bin/time -f "%e" -o t.txt "$R" bake "$input" -o out.ply -q --report rep.json $opts
  python3 - "$name" <<'PY'
import json, sys
e = json.load(open("est.json"))["estimate"]
r = json.load(open("rep.json"))
t = float(open("t.txt").read().split()[-1])
print(f"| {sys.argv[1]} | {e['method']} | {e['patches']} | {e['max_patches']} | "
      f"{e['memory_bytes'] / 2**20:.0f} | {e['seconds']:.1f} | {r['patches']} | "
      f"{r['peak_memory_bytes'] / 2**20:.0f} | {t:.1f} |")
PY
done < cases.txt
