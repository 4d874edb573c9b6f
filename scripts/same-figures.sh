#!/usr/bin/env bash
# Do two revisions give the same estimator figures? For moves that must change nothing.
#
#   scripts/same-figures.sh BASE_REV [NEW_REV] [OUT_DIR]
#
# Builds `examples/reproduce` at each revision (NEW_REV defaults to the working tree's HEAD) in
# throw-away worktrees with their own target directories under OUT_DIR (default
# target/same-figures; a target directory shared between checkouts can reuse another checkout's
# build), runs the default tables, `--faults`, `--delay-suite` and `--seeds 20`, and compares the
# JSON leaf by leaf, timing fields (`us_per_imu_sample*`) aside. Prints the differences of each
# file and exits 1 when there are any.
# Used for issue 23's moves: scripts/same-figures.sh cc1addc
set -euo pipefail
base=${1:?base revision}; new=${2:-HEAD}; out=${3:-target/same-figures}
root=$(git rev-parse --show-toplevel)
mkdir -p "$out"; out=$(cd "$out" && pwd)
for rev in "$base" "$new"; do
  sha=$(git -C "$root" rev-parse --short=12 "$rev")
  tree="$out/tree-$sha"; dir="$out/$sha"; mkdir -p "$dir"
  [ -d "$tree" ] || git -C "$root" worktree add --detach -q "$tree" "$sha"
  echo "building $rev ($sha)"
  (cd "$tree" && CARGO_TARGET_DIR="$out/target-$sha" \
     cargo build -q --release --features sim --example reproduce)
  bin="$out/target-$sha/release/examples/reproduce"
  for run in "default:" "faults:--faults" "delay:--delay-suite" "mc20:--seeds 20"; do
    name=${run%%:*}; flags=${run#*:}
    echo "  $name"
    # shellcheck disable=SC2086
    "$bin" $flags --json "$dir/$name.json" --plots "$dir/plots-$name" > "$dir/$name.txt" 2>&1
  done
  git -C "$root" worktree remove --force "$tree"
done
python3 "$root/scripts/results-diff.py" --dirs \
  "$out/$(git -C "$root" rev-parse --short=12 "$base")" \
  "$out/$(git -C "$root" rev-parse --short=12 "$new")" default faults delay mc20
