#!/usr/bin/env python3
"""Reads the firmware's semihosting logs (one per estimator, maximum delay
and placement, `NAME-MS-PLACEMENT.txt`, tried in that order: larger delay
first, a static before the stack), writes the benchmark JSON, prints the table with the
limits of limits.json beside the figures and, with --check, exits 1 when a
limit is exceeded, when an estimator refused more pushes than limits.json's
`pushes.refused_max`, or has no estimate after the last sample. The logs of
the image that holds the navigator alone (`LOGS/nav-only/`, feature nav-only)
are reported apart, under `nav_only_image` in the JSON, and checked against
limits.json's `nav_only_image` (any figure an estimator entry names).
Called by `run`."""
import argparse
import json
import pathlib
import sys

ESTIMATORS = ["nav_estimated_f32", "nav_fixed_f32", "ekf16_f32", "aekf17_f32"]
# Run from the image that holds the navigator alone (`run`: feature nav-only).
NAV_ONLY = ["nav_estimated_f32", "nav_fixed_f32"]
FIGURES = [
    ("instructions_per_imu_sample_mean", "mean"),
    ("instructions_per_imu_sample_max", "max"),
    ("size_of_bytes", "size_of"),
    ("stack_peak_bytes", "stack_peak"),
    ("instructions_push_gps_mean", "gps_mean"),
    ("instructions_push_gps_max", "gps_max"),
    ("stack_peak_construct_bytes", "stack_peak_construct"),
    ("stack_peak_push_bytes", "stack_peak_push"),
]


def parse(path):
    """The first RESULT/OVERFLOW line of a log as a dict, with its kind."""
    for line in path.read_text(errors="replace").splitlines():
        words = line.split()
        if words and words[0] in ("RESULT", "OVERFLOW"):
            fields = dict(w.split("=", 1) for w in words[1:] if "=" in w)
            fields["kind"] = words[0]
            return fields
    return None


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--logs", required=True, type=pathlib.Path)
    ap.add_argument("--limits", required=True, type=pathlib.Path)
    ap.add_argument("--json", type=pathlib.Path)
    ap.add_argument("--check", action="store_true")
    args = ap.parse_args()
    limits = json.loads(args.limits.read_text())

    runs, first, outside = {}, {}, {}
    for name in ESTIMATORS:
        attempts = []
        for path in args.logs.glob(f"{name}-*.txt"):
            ms, placement = path.stem[len(name) + 1:].split("-")
            if placement == "outside":
                outside[name] = parse(path)
                continue
            attempts.append((-int(ms), placement != "static", int(ms), parse(path)))
        attempts = [(ms, r) for _, _, ms, r in sorted(attempts, key=lambda a: a[:2])]
        if not attempts or attempts[0][1] is None:
            sys.exit(f"no result for {name} in {args.logs}")
        first[name] = attempts[0]
        result = next(((ms, r) for ms, r in attempts if r and r["kind"] == "RESULT"), None)
        if result is None:
            tried = [f"{ms} ms {r['placement']}" for ms, r in attempts]
            o = outside.get(name)
            if not (o and o["kind"] == "RESULT"):
                sys.exit(f"{name} did not fit in any configuration tried: {tried}")
            # Fits nowhere in 128 KB: report the counts with the stack beyond it.
            print(f"{name} did not fit in any configuration tried: {tried}; "
                  "figures with the stack outside 128 KB")
            result = (int(float(o["max_delay_s"]) * 1000), o)
        runs[name] = result

    report = {"estimators": {}, "flash_bytes": None}
    for name in ESTIMATORS:
        ms, r = runs[name]
        entry = {key: int(r[field]) for key, field in FIGURES}
        if ms != first[name][0]:
            entry["max_delay_s"] = ms / 1000
        if r["placement"] != "static":
            entry["placement"] = r["placement"]
        o = outside.get(name)
        if o and o["kind"] == "RESULT" and o is not r:
            # Did not fit at 0.5 s at all: its counts with SRAM beyond 128 KB.
            entry["outside_128_kb_at_0_5_s"] = {key: int(o[field]) for key, field in FIGURES}
        report["estimators"][name] = entry
    # Flash of the main build (the one without the fallback instantiations).
    report["flash_bytes"] = int(runs["ekf16_f32"][1]["flash"])
    # The navigator alone in its image: at 0.5 s in a static, as in the
    # main image (the object is the same; only the code around it differs).
    alone = {}
    for name in NAV_ONLY:
        path = args.logs / "nav-only" / f"{name}-500-static.txt"
        r = parse(path) if path.exists() else None
        if r is None:
            sys.exit(f"no result for {name} in {path.parent}")
        alone[name] = r
    report["nav_only_image"] = {
        "estimators": {
            name: ({key: int(r[field]) for key, field in FIGURES} if r["kind"] == "RESULT"
                   else {"size_of_bytes": int(r["size_of"]), "overflow_phase": r["phase"]})
            for name, r in alone.items()
        },
        "flash_bytes": next((int(r["flash"]) for r in alone.values() if "flash" in r), None),
    }
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(report, indent=2) + "\n")

    print("Cortex-M4 (QEMU netduinoplus2, -icount shift=0): instructions, not cycles")
    head = (f"{'estimator':<18} {'max delay':>9} {'per IMU sample':>14} {'max':>8} {'imu':>7} "
            f"{'mag':>7} {'gps':>7} {'gps max':>8} {'estimate':>8} {'size_of':>8} "
            f"{'stack new':>9} {'stack push':>10}")
    print(head)
    print("-" * len(head))
    for name in ESTIMATORS:
        ms, r = runs[name]
        print(f"{name:<18} {ms / 1000:>8.2f}s {int(r['mean']):>14,} {int(r['max']):>8,} "
              f"{int(r['imu_mean']):>7,} {int(r['mag_mean']):>7,} {int(r['gps_mean']):>7,} "
              f"{int(r['gps_max']):>8,} {int(r['estimate_mean']):>8,} {int(r['size_of']):>8,} "
              f"{int(r['stack_peak_construct']):>9,} {int(r['stack_peak_push']):>10,}")
        o = outside.get(name)
        if o and o["kind"] == "RESULT" and o is not r:
            print(f"{'  (outside 128 KB)':<18} {float(o['max_delay_s']):>8.2f}s {int(o['mean']):>14,} "
                  f"{int(o['max']):>8,} {int(o['imu_mean']):>7,} {int(o['mag_mean']):>7,} "
                  f"{int(o['gps_mean']):>7,} {int(o['gps_max']):>8,} {int(o['estimate_mean']):>8,} "
                  f"{int(o['size_of']):>8,} {int(o['stack_peak_construct']):>9,} "
                  f"{int(o['stack_peak_push']):>10,}")
        errors = sum(int(r[k]) for k in ("imu_errors", "mag_errors", "gps_errors"))
        if errors:
            print(f"  {name}: {errors} pushes returned an error")
        fms, f = first[name]
        if f is not r:
            print(f"  {name}: does not fit 128 KB SRAM at {fms / 1000} s in a static: size_of "
                  f"{int(f['size_of']):,} B leaves {int(f['stack_available']):,} B of stack and "
                  f"{f['phase']} overflowed it; figures above at {ms / 1000} s with the object "
                  f"{ {'static': 'in a static', 'outside': 'on a stack reaching beyond 128 KB'}.get(r['placement'], 'on the stack (stack figures exclude it)')}")
    print("(mean/max per IMU sample: push_imu plus the magnetometer and GPS pushes of the same time step;"
          " imu/mag/gps: mean of each call; estimate() apart; stack in bytes, construction and the pushes,"
          " beyond the object)")
    print(f"flash: {report['flash_bytes']:,} bytes (the four estimators, semihosting and panic"
          " formatting; the embedded samples excluded)")

    print("\nThe navigator alone in an image (feature nav-only), 0.5 s, in a static")
    print(head)
    print("-" * len(head))
    for name, r in alone.items():
        if r["kind"] != "RESULT":
            print(f"{name:<18} did not fit: {r['phase']} overflowed {int(r['stack_available']):,} B"
                  " of stack")
            continue
        print(f"{name:<18} {float(r['max_delay_s']):>8.2f}s {int(r['mean']):>14,} "
              f"{int(r['max']):>8,} {int(r['imu_mean']):>7,} {int(r['mag_mean']):>7,} "
              f"{int(r['gps_mean']):>7,} {int(r['gps_max']):>8,} {int(r['estimate_mean']):>8,} "
              f"{int(r['size_of']):>8,} {int(r['stack_peak_construct']):>9,} "
              f"{int(r['stack_peak_push']):>10,}")
    flash_alone = report["nav_only_image"]["flash_bytes"]
    if flash_alone is not None:
        print(f"flash: {flash_alone:,} bytes (the navigator, semihosting and panic formatting)")

    failures = []
    unenforced = []
    print("\nLimits (issue 12, benches/cortex-m4/limits.json)")
    print(f"{'estimator':<26} {'figure':<34} {'measured':>10} {'limit':>10}  ok")
    for name, lim in limits["estimators"].items():
        ms, r = runs[name]
        if abs(ms / 1000 - lim["max_delay_s"]) > 1e-9 or r["placement"] != "static":
            failures.append(f"{name} does not construct into a static at {lim['max_delay_s']} s")
            print(f"{name:<26} {'constructs into a static at':<34} {'no':>10} {str(lim['max_delay_s']) + ' s':>10}  NO")
        entry = report["estimators"][name]
        at_limit = entry.get("outside_128_kb_at_0_5_s", entry)
        for key, _ in FIGURES:
            if key in lim:
                value = at_limit[key]
                if key == "size_of_bytes":
                    value = int(first[name][1]["size_of"])
                ok = value <= lim[key]
                known = key in lim.get("not_enforced", [])
                if not ok:
                    (unenforced if known else failures).append(f"{name} {key} {value} > {lim[key]}")
                verdict = "yes" if ok else ("NO (not enforced: not_enforced in limits.json)"
                                            if known else "NO")
                print(f"{name:<26} {key:<34} {value:>10,} {lim[key]:>10,}  {verdict}")
    for name, lim in limits.get("nav_only_image", {}).get("estimators", {}).items():
        r = alone[name]
        label = f"{name} (alone)"
        if r["kind"] != "RESULT":
            failures.append(f"{label} does not construct into a static and run at 0.5 s")
            print(f"{label:<26} {'fits and runs in a static at 0.5 s':<34} {'no':>10} "
                  f"{'yes':>10}  NO")
            continue
        entry = report["nav_only_image"]["estimators"][name]
        for key, _ in FIGURES:
            if key in lim:
                ok = entry[key] <= lim[key]
                if not ok:
                    failures.append(f"{label} {key} {entry[key]} > {lim[key]}")
                print(f"{label:<26} {key:<34} {entry[key]:>10,} {lim[key]:>10,}  "
                      f"{'yes' if ok else 'NO'}")
    pushes = limits.get("pushes", {})
    refused_max = pushes.get("refused_max", 0)
    checked = [(n, runs[n][1]) for n in ESTIMATORS] + [
        (f"{n} (alone)", r) for n, r in alone.items() if r["kind"] == "RESULT"]
    for name, r in checked:
        refused = {k: int(r[f"{k}_errors"]) for k in ("imu", "mag", "gps")}
        total = sum(refused.values())
        ok = total <= refused_max
        if not ok:
            failures.append(f"{name}: {total} pushes refused (imu {refused['imu']}, "
                            f"mag {refused['mag']}, gps {refused['gps']}) > {refused_max}")
        print(f"{name:<26} {'refused pushes':<34} {total:>10,} {'<= ' + str(refused_max):>10}"
              f"  {'yes' if ok else 'NO'}")
        if pushes.get("estimate_at_end", True):
            # A firmware that does not report it has not shown an estimate.
            has = r.get("final_estimate") == "1"
            if not has:
                failures.append(f"{name}: no estimate after the last sample")
            print(f"{name:<26} {'estimate after the last sample':<34} "
                  f"{'yes' if has else 'no':>10} {'yes':>10}  {'yes' if has else 'NO'}")
    for ratio in limits.get("ratios", []):
        num = report["estimators"][ratio["numerator"]][ratio["figure"]]
        den = report["estimators"][ratio["denominator"]][ratio["figure"]]
        value = num / den
        ok = value >= ratio["min"]
        label = f"{ratio['numerator']} / {ratio['denominator']}"
        if not ok:
            failures.append(f"{label} {ratio['figure']} {value:.2f} < {ratio['min']}")
        print(f"{label:<61} {value:>10.2f} {'>= ' + str(ratio['min']):>10}  {'yes' if ok else 'NO'}")
    for u in unenforced:
        print(f"\nNOT MET (printed, not enforced): {u}")
    if failures:
        print(f"\n{len(failures)} limit(s) exceeded")
        if args.check:
            sys.exit(1)
    elif unenforced:
        print(f"\nevery enforced limit holds; {len(unenforced)} limit(s) not met and not enforced")
    else:
        print("\nall limits hold")


if __name__ == "__main__":
    main()
