#!/usr/bin/env python3
"""Counts the crate's public items, by kind, as rustdoc sees them (issue 23's measure).

    cargo +nightly rustdoc --lib -- -Z unstable-options --output-format json
    python3 scripts/public-api.py target/doc/delaynav.json [--json OUT]

With --json, also writes the counts by kind and their total as JSON (what
scripts/results.sh keeps in docs/results/public-api.json for docs/api.md).

Walks from the crate root through public modules, public items and `pub use`
re-exports; counts each item once; counts the public inherent methods and
associated constants of public structs, enums and traits ("method",
"assoc_const"). Default features unless the rustdoc command enables others.
"""
import argparse
import collections
import json
import sys


def count(path):
    doc = json.load(open(path))
    index = doc["index"]
    counts = collections.Counter()
    seen = set()

    def item(i):
        return index.get(str(i))

    def kind(it):
        return next(iter(it["inner"]))

    def visit(i, top=False):
        if i in seen:
            return
        seen.add(i)
        it = item(i)
        if it is None or (not top and it.get("visibility") != "public"):
            return
        k = kind(it)
        inner = it["inner"][k]
        if k == "use":
            if inner.get("id") is not None:
                visit(inner["id"])
            return
        counts[k] += 1
        if k == "module":
            for c in inner["items"]:
                visit(c)
        elif k in ("struct", "enum", "trait"):
            for impl_id in inner.get("impls", []):
                impl = item(impl_id)
                if impl is None or impl["inner"]["impl"].get("trait") is not None:
                    continue
                for c in impl["inner"]["impl"]["items"]:
                    ci = item(c)
                    if ci and ci.get("visibility") == "public":
                        counts["method" if kind(ci) == "function" else kind(ci)] += 1

    visit(doc["root"], top=True)
    return counts


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("path", nargs="?", default="target/doc/delaynav.json")
    ap.add_argument("--json", metavar="OUT", help="also write the counts as JSON")
    args = ap.parse_args()
    counts = count(args.path)
    for k, n in sorted(counts.items()):
        print(f"{k:>14} {n}")
    total = sum(counts.values())
    print(f"{'total':>14} {total}")
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"by_kind": dict(sorted(counts.items())), "total": total}, f, indent=2)
            f.write("\n")


if __name__ == "__main__":
    sys.exit(main())
