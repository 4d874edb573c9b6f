#!/usr/bin/env python3
"""Compares docs/results/*.json in the working tree with a revision's (default HEAD), leaf by leaf,
timing fields (`us_per_imu_sample*`) aside: after `scripts/results.sh`, it tells whether any figure
moved or only the timings did.

    python3 scripts/results-diff.py [REV]
    python3 scripts/results-diff.py --dirs A B NAME...   # A/NAME.json against B/NAME.json

Prints the differences per file (at most 8 each) and exits 1 when there are any.
"""
import glob
import json
import os
import subprocess
import sys


def walk(a, b, path, out):
    if isinstance(a, dict) and isinstance(b, dict):
        for k in sorted(set(a) | set(b)):
            if k.startswith("us_per_imu_sample"):
                continue
            if k not in a or k not in b:
                out.append(f"{path}.{k}: only in one")
            else:
                walk(a[k], b[k], f"{path}.{k}", out)
    elif isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
        for i, (x, y) in enumerate(zip(a, b)):
            walk(x, y, f"{path}[{i}]", out)
    elif a != b:
        out.append(f"{path}: {a!r} vs {b!r}")


def main(rev):
    root = subprocess.run(["git", "rev-parse", "--show-toplevel"], capture_output=True, text=True, check=True).stdout.strip()
    os.chdir(root)
    total = 0
    for f in sorted(glob.glob("docs/results/*.json")):
        old = subprocess.run(["git", "show", f"{rev}:{f}"], capture_output=True, text=True)
        if old.returncode != 0:
            print(f"{f}: not in {rev}")
            total += 1
            continue
        out = []
        walk(json.loads(old.stdout), json.load(open(f)), os.path.basename(f), out)
        print(f"{f}: {len(out)} differences")
        for line in out[:8]:
            print("  " + line)
        total += len(out)
    return 1 if total else 0


def dirs(a_dir, b_dir, names):
    total = 0
    for name in names:
        out = []
        walk(json.load(open(f"{a_dir}/{name}.json")), json.load(open(f"{b_dir}/{name}.json")), name, out)
        print(f"{name}.json: {len(out)} differences")
        for line in out[:20]:
            print("  " + line)
        total += len(out)
    return 1 if total else 0


if __name__ == "__main__":
    if len(sys.argv) > 1 and sys.argv[1] == "--dirs":
        sys.exit(dirs(sys.argv[2], sys.argv[3], sys.argv[4:]))
    sys.exit(main(sys.argv[1] if len(sys.argv) > 1 else "HEAD"))
