#!/usr/bin/env bash
# Paired per-seed comparison of two revisions on the simulator.
#
#   scripts/paired-seeds.sh BASE_REV NEW_REV DELAY_S [SEEDS] [OUT_DIR]
#
# Builds `examples/reproduce` at each revision (in throw-away worktrees with
# their own target directories under OUT_DIR), runs
# `reproduce --delay DELAY_S --seed S --seeds 1` for seeds 1..SEEDS (20) with
# each build, and prints, per scenario, estimator and figure, the mean of each
# build and the mean paired difference (NEW - BASE) with its 95 % interval
# (1.96 standard errors of the mean difference).
# Used for docs/nav.md, "Averaging, not dropping":
#   scripts/paired-seeds.sh c9dd280 <the averaging commit> 0.6
set -euo pipefail
base=${1:?base revision}; new=${2:?new revision}; delay=${3:?delay, s}
seeds=${4:-20}; out=${5:-target/paired-seeds}
root=$(git rev-parse --show-toplevel)
mkdir -p "$out"; out=$(cd "$out" && pwd)
for rev in "$base" "$new"; do
  tree="$out/tree-$rev"
  [ -d "$tree" ] || git -C "$root" worktree add --detach -q "$tree" "$rev"
  (cd "$tree" && CARGO_TARGET_DIR="$out/target-$rev" \
     cargo build -q --release --features sim --example reproduce)
  for s in $(seq 1 "$seeds"); do
    "$out/target-$rev/release/examples/reproduce" --delay "$delay" --seed "$s" --seeds 1 \
      --json "$out/$rev-d$delay-s$s.json" > /dev/null 2>&1
  done
  git -C "$root" worktree remove --force "$tree"
done
python3 - "$out" "$base" "$new" "$delay" "$seeds" <<'PY'
import json, statistics as st, sys
out, base, new, delay, seeds = sys.argv[1], sys.argv[2], sys.argv[3], sys.argv[4], int(sys.argv[5])
def load(rev, s):
    return {sc['name']: sc['estimators'] for sc in json.load(open(f'{out}/{rev}-d{delay}-s{s}.json'))['scenarios']}
runs = [(load(base, s), load(new, s)) for s in range(1, seeds + 1)]
for scenario in runs[0][0]:
    for est in ('proposed', 'oracle'):
        for fig in ('tilt_deg', 'heading_deg', 'vel_m_s', 'pos_m'):
            a = [b[scenario][est][fig] for b, _ in runs]
            b = [n[scenario][est][fig] for _, n in runs]
            d = [y - x for x, y in zip(a, b)]
            ci = 1.96 * st.stdev(d) / len(d) ** 0.5
            print(f'{scenario:5} {est:9} {fig:12} base {st.mean(a):.4f} new {st.mean(b):.4f} '
                  f'diff {st.mean(d):+.4f} +- {ci:.4f} ({100 * st.mean(d) / st.mean(a):+.1f} %)')
PY
