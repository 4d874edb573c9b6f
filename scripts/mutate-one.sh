#!/usr/bin/env bash
# One hand-written mutation: replace OLD by NEW in FILE (it must occur once), run the whole test
# suite, restore the file, and say whether a test caught it and which.
#
#   scripts/mutate-one.sh NAME FILE OLD NEW
#
# For mutations cargo-mutants does not make (a flag forced true, a state reported as another);
# scripts/mutants.sh runs cargo-mutants itself. Runs in this checkout: do not edit FILE meanwhile.
set -u
name=$1 file=$2 old=$3 new=$4
cd "$(git rev-parse --show-toplevel)"
backup=$(mktemp)
cp "$file" "$backup"
trap 'cp "$backup" "$file"; rm -f "$backup"' EXIT
python3 - "$file" "$old" "$new" <<'PY'
import sys
path, old, new = sys.argv[1:]
text = open(path).read()
if text.count(old) != 1:
    sys.exit(f"{old!r} occurs {text.count(old)} times in {path}")
open(path, "w").write(text.replace(old, new))
PY
out=$(cargo test -q --all-features --no-fail-fast 2>&1)
failed=$(echo "$out" | grep -E '^    [A-Za-z_0-9:]+$' | sort -u | tr -s ' \n' ' ')
if echo "$out" | grep -q 'test result: FAILED\|error: test failed\|could not compile'; then
  echo "$name: caught by:$failed"
else
  echo "$name: MISSED"
fi
