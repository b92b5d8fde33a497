#!/usr/bin/env bash
# Quake-class levels at the defaults: LibreQuake's level sources (BSD-licensed; .map files as
# TrenchBroom keeps them) converted by tools/quake_map.py, then `info` (the estimate) and a
# default bake with the level's own lights (its lamps, sun and sky in the lights file). Prints
# the converter's counts, the estimate and the bake's patches, vertices, peak memory and wall
# seconds (BENCHMARKS.md, "A Quake-class level").
# Usage: bash tools/bench_quake.sh LIBREQUAKE_CHECKOUT [LEVEL ...]
#   (default levels: e1/lq_e1m2 e1/lq_e1m1 e4/lq_e4m3)
set -euo pipefail
lq="$(cd "$1" && pwd)"; shift
levels=("$@"); [ ${#levels[@]} -eq 0 ] && levels=(e1/lq_e1m2 e1/lq_e1m1 e4/lq_e4m3)
cd "$(dirname "$0")/.."
cargo build --release --quiet
R="$PWD/target/release/radiosity"
tools="$PWD/tools"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
cd "$work"
for level in "${levels[@]}"; do
  name="$(basename "$level")"
  python3 "$tools/quake_map.py" "$lq/lq1/maps/src/$level.map" -o "$name.obj" --textures "$lq/texture-wads"
  "$R" info "$name.obj" --up z --lights "$name.lights.json" | grep -E '^(method|patches|estimate):'
  /usr/bin/time -f "$name: %e s wall, %M KiB peak" \
    "$R" bake "$name.obj" -o "$name.ply" --up z --lights "$name.lights.json" -q --report "$name.json" 2>&1 \
    | grep -v -E '^(warning|  )' || true
  python3 -c "
import json; r = json.load(open('$name.json'))
h = r.get('hierarchical') or {}
print('$name: patches', r['patches'], 'vertices', r['vertices'], 'links', h.get('links'), 'gather', r['gather'],
      'seconds', {k: round(v, 2) for k, v in r['seconds'].items() if v > 0.05})"
done
