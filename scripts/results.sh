#!/usr/bin/env bash
# Regenerates the JSON behind every table of figures in the manual, into docs/results/.
#
#   scripts/results.sh [--only NAME[,NAME...]]
#
# Runs each suite that feeds a `<!-- figures:begin NAME -->` block (the simulator tables at
# 20 seeds, the bound study, the three sweeps, the fault suite, the delay suite at 5 and 20
# seeds, the Cortex-M4 bench under QEMU, the log171 replays from ../shared/data, the memory
# test of src/nav/memory.rs), then renders the markdown from the JSON with scripts/figures.py.
# NAME is one of the step names printed (e.g. `--only faults,cortex-m4`); without it every step
# runs. Each step prints its name and its time, and what it printed goes to
# target/results/NAME.log; the whole takes 6.5 min on a 2-core machine once built, 15 min with
# the first builds (docs/results/README.md).
# `python3 scripts/figures.py --check` (CI) fails when the markdown differs from the JSON.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
cd "$root"
out=docs/results
data=../shared/data/ardupilot-log171

only=""
while [ $# -gt 0 ]; do
  case "$1" in
    --only) only=",${2:?--only needs names},"; shift 2 ;;
    -h|--help) sed -n '2,14p' "$0"; exit 0 ;;
    *) echo "unknown argument: $1" >&2; exit 2 ;;
  esac
done

wanted() { [ -z "$only" ] || [[ "$only" == *",$1,"* ]]; }
started=$SECONDS
logs=target/results
mkdir -p "$logs"
# One step: its name, its time; what it prints goes to target/results/NAME.log (its tail is
# shown when it fails).
step() {
  local name="$1"
  shift
  wanted "$name" || return 0
  local t=$SECONDS
  printf '%-16s ' "$name" >&2
  if ! "$@" >"$logs/$name.log" 2>&1; then
    printf 'FAILED after %d s; the end of %s:\n' $((SECONDS - t)) "$logs/$name.log" >&2
    tail -20 "$logs/$name.log" >&2
    exit 1
  fi
  printf '%4d s\n' $((SECONDS - t)) >&2
}

echo "building the reproduce example and the delaynav command (release)" >&2
cargo build --release --all-features --example reproduce
cargo build --release -p delaynav-cli
bin="${CARGO_TARGET_DIR:-target}/release"
reproduce() { "$bin/examples/reproduce" "$@"; }
replay() { "$bin/delaynav" replay "$@"; }
hand_tuned=(--accel-noise-density 0.05 --gyro-noise-density 0.005 --declination-deg 11.8)
sim_defaults=(--accel-noise-density 0.031 --gyro-noise-density 0.0013 --declination-deg 0)


log171() {
  if [ ! -d "$data" ]; then
    echo "$data is missing: the log171 replays cannot run" >&2
    return 1
  fi
  replay "$data/log171.bin" --json "$out/log171-log-derived.json" || return 1
  replay "$data/log171.bin" --json "$out/log171-hand-tuned.json" "${hand_tuned[@]}" || return 1
  replay "$data/log171.bin" --json "$out/log171-sim-defaults.json" "${sim_defaults[@]}" || return 1
  for d in 0 0.1 0.2 0.3; do
    replay "$data" --from 75 --to 225 --estimator all --add-gps-delay "$d" \
      --json "$out/log171-table7-$d.json" "${hand_tuned[@]}" || return 1
  done
  replay "$data" --from 75 --to 225 --estimator all --add-gps-delay 0.2 --add-delay-from 150 \
    --json "$out/log171-step.json" "${hand_tuned[@]}" --quiet || return 1
  # Yaw without the magnetometer, from 30 s after the take-off (84.668 s) to the window's end.
  replay "$data/log171.bin" --estimator proposed --from 114.668 --no-mag \
    --json "$out/log171-no-mag.json" --quiet || return 1
  replay "$data/log171.bin" --estimator proposed --from 114.668 \
    --json "$out/log171-with-mag-from-114.json" --quiet || return 1
}
step log171 log171
step faults reproduce --faults --json "$out/faults.json"
step faults-seeds reproduce --faults --seed 1 --seeds 5 --json "$out/faults-seeds.json"
step integrity reproduce --integrity --json "$out/integrity.json"
step delay-suite reproduce --delay-suite --json "$out/delay-suite.json"
step cortex-m4 benches/cortex-m4/run --json "$out/cortex-m4.json"
step monte-carlo reproduce --seeds 20 --json "$out/results.json"
step delay-suite-20 reproduce --delay-suite --seeds 20 --json "$out/delay-suite-20.json"
for s in gps_rate imu_rate delay; do
  step "sweep-$s" reproduce --sweep "$s" --seeds 5 --json "$out/sweep-$s.json"
done
# The navigator's host `size_of`, member by member at HIST 530 (src/nav/memory.rs) and whole
# at the default HIST and 256 (tests/nav_alloc.rs); their printed lines parsed here.
nav_memory() {
  {
    cargo test --all-features --lib size_of_every_member_at_half_a_second -- --nocapture \
      --test-threads 1
    cargo test --all-features --test nav_alloc memory_footprint -- --nocapture --test-threads 1
  } | python3 scripts/figures.py --parse-nav-memory "$out/nav-memory.json"
}
step nav-memory nav_memory
step bound-study reproduce --seeds 20 --bound-study --json "$out/bound-study.json"
# The public items by kind (scripts/public-api.py on rustdoc's JSON, nightly), default features,
# then with the hidden `internals` (docs/api.md, "Size").
public_api() {
  local doc="${CARGO_TARGET_DIR:-target}/doc/delaynav.json"
  cargo +nightly rustdoc --lib -- -Z unstable-options --output-format json
  python3 scripts/public-api.py "$doc" --json "$out/public-api.json"
  cargo +nightly rustdoc --lib -- -Z unstable-options --output-format json --document-hidden-items
  python3 scripts/public-api.py "$doc" --json "$out/public-api-hidden.json"
}
step public-api public_api

echo "rendering the markdown" >&2
python3 scripts/figures.py
printf 'done in %d s\n' $((SECONDS - started)) >&2
