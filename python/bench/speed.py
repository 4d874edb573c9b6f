"""Speed of the Python package against the Rust it wraps, on log171:

1. ``delaynav.replay`` (the proposed estimator, every estimate kept as
   arrays) against the command line's replay of the same log
   (``delaynav replay LOG --estimator proposed --json FILE --quiet``, the
   process included);
2. ``Navigator.push_imu_array`` against the Rust per-sample loop of the
   ``stream`` example (``--imu-only``: the log's IMU samples pushed into a
   fresh navigator, the records read and the navigator made before the
   clock starts, on both sides).

Medians of ``--runs`` runs (and, for the IMU loop, whose run lasts about
2 ms, the least of them too: on a shared machine the median of so short a
run follows the other load); the ratios' target is 1.2 at most. Needs the
release builds of the command and the example:

    cargo build --release -p delaynav-cli
    cargo build --release --features replay --example stream
    python python/bench/speed.py [--log PATH] [--runs 9] [--json out.json]
"""

from __future__ import annotations

import argparse
import json
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import delaynav

REPO = Path(__file__).resolve().parents[2]


def times_of(fn, runs: int) -> list[float]:
    times = []
    for _ in range(runs):
        started = time.perf_counter()
        fn()
        times.append(time.perf_counter() - started)
    return times


def median_time(fn, runs: int) -> float:
    return statistics.median(times_of(fn, runs))


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--log", default=str(REPO.parent / "shared/data/ardupilot-log171/log171.bin"))
    parser.add_argument("--runs", type=int, default=9)
    parser.add_argument("--target", default=str(REPO / "target"))
    parser.add_argument("--json", help="write the figures as JSON")
    args = parser.parse_args(argv)
    cli = Path(args.target) / "release" / "delaynav"
    stream = Path(args.target) / "release" / "examples" / "stream"
    for binary in (cli, stream):
        if not binary.exists():
            print(f"{binary} is missing: build it first (see the module docs)", file=sys.stderr)
            return 2

    # 1. The replay.
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "summary.json"
        command = [str(cli), "replay", args.log, "--estimator", "proposed", "--json", str(out), "--quiet"]
        run_cli = lambda: subprocess.run(command, check=True, capture_output=True)  # noqa: E731
        run_cli()
        cli_s = median_time(run_cli, args.runs)
        cli_summary = json.loads(out.read_text())
    delaynav.replay(args.log)
    python_s = median_time(lambda: delaynav.replay(args.log), args.runs)
    assert delaynav.replay(args.log).summary == cli_summary

    # 2. The IMU loop.
    rust = subprocess.run(
        [str(stream), args.log, "--imu-only", "--repeat", str(args.runs)],
        check=True,
        capture_output=True,
        text=True,
    ).stdout
    found = re.search(r"median ([0-9.]+) ns per sample, min ([0-9.]+) ns", rust)
    rust_ns, rust_min_ns = float(found.group(1)), float(found.group(2))
    imu = delaynav.read_log(args.log)["imu"]
    n = len(imu["t_us"])

    # A fresh navigator per run, made before the clock starts (as the Rust loop's).
    def push_times_of(runs: int) -> list[float]:
        times = []
        for _ in range(runs):
            nav = delaynav.Navigator()
            started = time.perf_counter()
            nav.push_imu_array(imu["t_us"], imu["gyro_rad_s"], imu["accel_m_s2"], errors="skip")
            times.append(time.perf_counter() - started)
        return times

    push_times_of(1)
    push_times = push_times_of(args.runs)
    python_ns = statistics.median(push_times) / n * 1e9
    python_min_ns = min(push_times) / n * 1e9

    figures = {
        "log": args.log,
        "runs": args.runs,
        "replay_cli_s": round(cli_s, 4),
        "replay_python_s": round(python_s, 4),
        "replay_ratio": round(python_s / cli_s, 3),
        "imu_samples": n,
        "push_rust_ns_per_sample": round(rust_ns, 1),
        "push_imu_array_ns_per_sample": round(python_ns, 1),
        "push_ratio": round(python_ns / rust_ns, 3),
        "push_rust_min_ns_per_sample": round(rust_min_ns, 1),
        "push_imu_array_min_ns_per_sample": round(python_min_ns, 1),
        "push_min_ratio": round(python_min_ns / rust_min_ns, 3),
    }
    print(
        f"replay of {Path(args.log).name}: command line {cli_s:.3f} s, Python {python_s:.3f} s "
        f"(ratio {python_s / cli_s:.2f}; median of {args.runs})"
    )
    print(
        f"IMU loop, {n} samples: Rust {rust_ns:.0f} ns/sample, push_imu_array {python_ns:.0f} ns/sample "
        f"(ratio {python_ns / rust_ns:.2f}); least of {args.runs}: Rust {rust_min_ns:.0f}, "
        f"push_imu_array {python_min_ns:.0f} ns/sample (ratio {python_min_ns / rust_min_ns:.2f})"
    )
    if args.json:
        Path(args.json).write_text(json.dumps(figures, indent=2) + "\n")
    ok = figures["replay_ratio"] <= 1.2 and figures["push_ratio"] <= 1.2
    print("within 1.2x" if ok else "NOT within 1.2x")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
