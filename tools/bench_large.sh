#!/usr/bin/env bash
# Large scenes: the estimate `radiosity info` makes before a bake against the bake itself, at
# the defaults plus each scene's lights. For each scene: roots, the estimate's seconds, peak
# memory and links (the pilot's count), and the bake's wall seconds, peak memory (VmHWM),
# links, links per element, sweeps, and seconds of its solve and gather (BENCHMARKS.md,
# "Large scenes: the estimate against the bake"). About 10 minutes on 2 cores.
# Usage: bash tools/bench_large.sh [LIBREQUAKE_CHECKOUT]
#   With a LibreQuake checkout (github.com/fpiesche/LibreQuake), three of its levels are
#   converted by tools/quake_map.py and baked with their own lights (--up z --lights);
#   the generated office and halls are always baked.
set -euo pipefail
lq=""
[ $# -ge 1 ] && lq="$(cd "$1" && pwd)"
cd "$(dirname "$0")/.."
cargo build --release --quiet
R="$PWD/target/release/radiosity"
tools="$PWD/tools"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
cd "$work"
cases=()
if [ -n "$lq" ]; then
  for level in e1/lq_e1m1 e4/lq_e4m3 e1/lq_e1m5; do
    name="$(basename "$level")"
    python3 "$tools/quake_map.py" "$lq/lq1/maps/src/$level.map" -o "$name.obj" \
      --textures "$lq/texture-wads" > /dev/null
    cases+=("$name|$name.obj|--up z --lights $name.lights.json")
  done
fi
"$R" generate office --triangles 100000 -o office1e5.obj > /dev/null
"$R" generate office --triangles 130000 -o office13e4.obj > /dev/null
"$R" generate hall --triangles 10000 -o hall1e4.obj > /dev/null
"$R" generate hall --triangles 100000 -o hall1e5.obj > /dev/null
cases+=("office 10^5|office1e5.obj|--up z" "office 1.3*10^5|office13e4.obj|--up z"
  "hall 10^4|hall1e4.obj|" "hall 10^5|hall1e5.obj|")
echo "| scene | roots | est. s | s | est. MiB | peak MiB | links: pilot / bake | links per element | sweeps | pilot s | solve s | gather s: est. / bake |"
echo "|---|---|---|---|---|---|---|---|---|---|---|---|"
for c in "${cases[@]}"; do
  IFS='|' read -r name input opts <<< "$c"
  # shellcheck disable=SC2086
  "$R" info "$input" --json $opts > est.json
  # shellcheck disable=SC2086
  /usr/bin/time -f "%e" -o t.txt "$R" bake "$input" -o out.ply -q --report rep.json $opts \
    2> /dev/null
  python3 - "$name" <<'PY'
import json, sys
e = json.load(open("est.json"))["estimate"]
r = json.load(open("rep.json"))
t = float(open("t.txt").read().split()[-1])
h = r.get("hierarchical") or {}
p = e.get("pilot") or {}
s = r["seconds"]
links = h.get("links") or 0
per = links / h["elements"] if h.get("elements") else float("nan")
print(f"| {sys.argv[1]} | {e['patches']:,} | {e['seconds']:.0f} | {t:.1f} | "
      f"{e['memory_bytes'] / 2**20:.0f} | {r['peak_memory_bytes'] / 2**20:.0f} | "
      f"{p.get('links', 0) / 1e6:.2f} M / {links / 1e6:.2f} M | {per:.0f} | {h.get('sweeps')} | "
      f"{p.get('seconds', 0):.1f} | {s.get('solve', 0):.1f} | "
      f"{e['gather_seconds']:.0f} / {s.get('gather', 0):.1f} |")
PY
done
