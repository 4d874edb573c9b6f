#!/usr/bin/env bash
# Do two revisions give the same estimator figures? For moves that must change nothing.
#
#   scripts/same-figures.sh BASE_REV [NEW_REV] [OUT_DIR]
#
# Builds `examples/reproduce` at each revision (NEW_REV defaults to the working tree's HEAD) in
# throw-away worktrees with their own target directories under OUT_DIR (default
# target/same-figures; a target directory shared between checkouts can reuse another checkout's
# build), runs the default tables, `--faults`, `--delay-suite` and `--seeds 20`, and compares the
# JSON leaf by leaf, timing fields (`us_per_imu_sample*`) aside. With ../shared/data beside the
# checkout (or DELAYNAV_SHARED_DATA), also builds the replay (`delaynav replay`, or `examples/replay`
# at revisions before the command) and compares the log171
# replays of scripts/results.sh (no flag on log171.bin, the Table 7 run with 0.2 s added, the
# delay step). Prints the differences of each file and exits 1 when there are any.
# Used for issue 23's moves: scripts/same-figures.sh cc1addc
set -euo pipefail
base=${1:?base revision}; new=${2:-HEAD}; out=${3:-target/same-figures}
root=$(git rev-parse --show-toplevel)
mkdir -p "$out"; out=$(cd "$out" && pwd)
data=${DELAYNAV_SHARED_DATA:-$root/../shared/data}/ardupilot-log171
names="default faults delay mc20"
[ -d "$data" ] && names="$names log171 table7-0.2 step"
hand_tuned=(--accel-noise-density 0.05 --gyro-noise-density 0.005 --declination-deg 11.8)
for rev in "$base" "$new"; do
  sha=$(git -C "$root" rev-parse --short=12 "$rev")
  tree="$out/tree-$sha"; dir="$out/$sha"; mkdir -p "$dir"
  [ -d "$tree" ] || git -C "$root" worktree add --detach -q "$tree" "$sha"
  echo "building $rev ($sha)"
  if [ -d "$tree/examples/replay" ]; then
    (cd "$tree" && CARGO_TARGET_DIR="$out/target-$sha" \
       cargo build -q --release --all-features --example reproduce --example replay)
    replay=("$out/target-$sha/release/examples/replay")
  else
    (cd "$tree" && CARGO_TARGET_DIR="$out/target-$sha" \
       cargo build -q --release --all-features --example reproduce && cargo build -q --release -p delaynav-cli)
    replay=("$out/target-$sha/release/delaynav" replay)
  fi
  bin="$out/target-$sha/release/examples/reproduce"
  for run in "default:" "faults:--faults" "delay:--delay-suite" "mc20:--seeds 20"; do
    name=${run%%:*}; flags=${run#*:}
    echo "  $name"
    # shellcheck disable=SC2086
    "$bin" $flags --json "$dir/$name.json" --plots "$dir/plots-$name" > "$dir/$name.txt" 2>&1
  done
  if [ -d "$data" ]; then
    echo "  log171 replays"
    "${replay[@]}" "$data/log171.bin" --json "$dir/log171.json" > "$dir/log171.txt" 2>&1
    "${replay[@]}" "$data" --from 75 --to 225 --estimator all --add-gps-delay 0.2 \
      --json "$dir/table7-0.2.json" "${hand_tuned[@]}" > "$dir/table7-0.2.txt" 2>&1
    "${replay[@]}" "$data" --from 75 --to 225 --estimator all --add-gps-delay 0.2 --add-delay-from 150 \
      --json "$dir/step.json" "${hand_tuned[@]}" --quiet > "$dir/step.txt" 2>&1
  fi
  git -C "$root" worktree remove --force "$tree"
done
python3 "$root/scripts/results-diff.py" --dirs \
  "$out/$(git -C "$root" rev-parse --short=12 "$base")" \
  "$out/$(git -C "$root" rev-parse --short=12 "$new")" $names
