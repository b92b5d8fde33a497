#!/usr/bin/env bash
# A bake over MPI ranks against the same bake in one process (README, "A bake over several
# machines"): `mpirun -n 2` and `-n 3` must write the very bytes one process writes, on the
# Cornell box (hierarchical, the default matrix bake with its gather, and the `cache`
# gather) and on the closed furnace; and a run that goes wrong must end with a non-zero
# status and write nothing: a setting that is wrong, an input that is missing, a rank killed
# in the middle of the bake.
#
# Usage: bash tools/mpi_check.sh
# Needs an MPI and libclang (Debian: libopenmpi-dev openmpi-bin libclang-dev).
# Exit status: 0 all hold, 1 one does not, 3 no MPI on this machine (nothing was checked).
set -euo pipefail
cd "$(dirname "$0")/.."
if ! command -v mpirun >/dev/null; then
  echo "mpi_check: no mpirun on this machine"
  exit 3
fi
# Open MPI refuses to start as root unless told; CI runs as root.
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
cargo build --release --quiet -p radiosity-cli --features mpi
bin="$PWD/target/release/radiosity"
out="$(mktemp -d)"
trap 'rm -rf "$out"' EXIT
fail() { echo "mpi_check: FAIL: $*"; exit 1; }

# name, then the bake's arguments after the output: one process, then 2 and 3 ranks.
same_bytes() {
  local name="$1" input="$2"; shift 2
  "$bin" -q bake "$input" -o "$out/$name.1.ply" "$@"
  for n in 2 3; do
    mpirun --oversubscribe -n "$n" "$bin" -q bake "$input" -o "$out/$name.$n.ply" "$@"
    cmp "$out/$name.1.ply" "$out/$name.$n.ply" || fail "$name: $n ranks wrote other bytes than one process"
    echo "mpi_check: $name: $n ranks wrote the bytes one process writes"
  done
}
same_bytes cornell-hierarchical meshes/cornell_box.obj --method hierarchical
same_bytes cornell-default meshes/cornell_box.obj
# The `cache` gather: its display refinement's tests share their direct light with the vertices.
same_bytes cornell-cache meshes/cornell_box.obj --gather cache
same_bytes furnace-hierarchical meshes/furnace.obj --method hierarchical

# A run that fails must leave what is on disk as it was.
echo "keep me" > "$out/kept.ply"
expect_failure() {
  local what="$1" says="$2"; shift 2
  set +e
  mpirun --oversubscribe -n 2 "$@" > "$out/log" 2>&1
  local status=$?
  set -e
  [ "$status" -ne 0 ] || fail "$what: exit status 0"
  grep -q -- "$says" "$out/log" || { cat "$out/log"; fail "$what: the message does not say '$says'"; }
  [ "$(cat "$out/kept.ply")" = "keep me" ] || fail "$what: the output on disk was touched"
  echo "mpi_check: $what: exit status $status, says '$says', nothing written"
}
expect_failure "a wrong setting" "rank 1 of 2" \
  "$bin" -q bake meshes/cornell_box.obj -o "$out/kept.ply" --epsilon 2
expect_failure "a missing input" "no_such_scene.obj" \
  "$bin" -q bake "$out/no_such_scene.obj" -o "$out/kept.ply"

# A rank killed in the middle: mpirun ends the others and the run.
"$bin" -q generate hall --triangles 20000 -o "$out/hall.obj"
set +e
mpirun --oversubscribe -n 2 "$bin" -q bake "$out/hall.obj" -o "$out/kept.ply" --method hierarchical \
  > "$out/log" 2>&1 &
run=$!
# Wait for both ranks, then kill one.
for _ in $(seq 100); do
  pids=$(pgrep -f "radiosity -q bake $out/hall.obj" || true)
  [ "$(echo "$pids" | wc -w)" -ge 2 ] && break
  sleep 0.1
done
sleep 2
victim=$(echo "$pids" | tr ' ' '\n' | sort -n | tail -1)
kill -9 "$victim"
wait "$run"
status=$?
set -e
[ "$status" -ne 0 ] || fail "a killed rank: exit status 0"
[ "$(cat "$out/kept.ply")" = "keep me" ] || fail "a killed rank: the output on disk was touched"
pgrep -f "radiosity -q bake $out/hall.obj" >/dev/null && fail "a killed rank: other ranks still run"
echo "mpi_check: a killed rank: exit status $status, the other rank ended, nothing written"
echo "mpi_check: all hold"
