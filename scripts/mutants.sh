#!/usr/bin/env bash
# Mutation testing of src/nav, src/delay and src/ekf16 at one revision: how many mutants the
# test suite catches (issue 23 asks for the figures before and after a change of the tests).
#
#   scripts/mutants.sh REV [sample|control] [OUT_DIR]
#
# Installs cargo-mutants when absent. Checks REV out in a throw-away worktree with its own target
# directory under OUT_DIR (default target/mutants; never share a target directory between
# checkouts: cargo would reuse the other checkout's build), and runs `cargo mutants --in-place
# --all-features` with the whole test suite (`cargo test --all-features`) on
#   sample:  a round-robin 1-in-80 sample of the three modules' mutants (55 of 4,371 on cc1addc);
#   control: the control decisions: health, alignment, the delay status, set_delay.
# Prints caught / missed / timeout / unviable; the lists are in OUT_DIR/REV-SET/mutants.out/.
# Cost: one incremental build and one test run per mutant, about a minute each on an idle
# 2-core machine; run the two revisions one after the other, not at once.
set -euo pipefail
rev=${1:?revision}; set_name=${2:-sample}; out=${3:-target/mutants}
root=$(git rev-parse --show-toplevel)
command -v cargo-mutants >/dev/null 2>&1 || cargo install cargo-mutants --locked
mkdir -p "$out"; out=$(cd "$out" && pwd)
case "$set_name" in
  sample) select=(--shard 0/80) ;;
  control) select=(--re '::health|::alignment|DelayStatus|::status|::set_delay|::is_estimating') ;;
  *) echo "unknown set: $set_name (sample or control)" >&2; exit 2 ;;
esac
sha=$(git -C "$root" rev-parse --short=12 "$rev")
tree="$out/tree-$sha"
[ -d "$tree" ] || git -C "$root" worktree add --detach -q "$tree" "$sha"
files=(-f 'src/nav/**' -f 'src/delay/**' -f 'src/ekf16/**')
# cargo-mutants exits 2 when a mutant was missed and 3 on a timeout: results, not failures.
rc=0
(cd "$tree" && CARGO_TARGET_DIR="$out/target-$sha" cargo mutants --in-place --all-features \
   "${files[@]}" "${select[@]}" -o "$out/$sha-$set_name") || rc=$?
case "$rc" in 0|2|3) ;; *) echo "cargo mutants failed ($rc)" >&2; exit "$rc" ;; esac
for kind in caught missed timeout unviable; do
  printf '%-9s %s\n' "$kind" "$(wc -l < "$out/$sha-$set_name/mutants.out/$kind.txt")"
done
git -C "$root" worktree remove --force "$tree"
