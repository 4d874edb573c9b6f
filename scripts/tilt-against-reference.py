#!/usr/bin/env python3
"""How much of the tilt difference from an ArduPilot log's onboard solution is the horizontal
accelerometer bias the crate's filters estimate and the onboard EKF of the log does not.

ArduPilot's first EKF (AP_NavEKF, the `EKF1` records of 2015 logs such as log171) has a vertical
accelerometer bias state only: a horizontal bias stays in its roll and pitch, where the crate's
filters move it into their bias states. This script compares the estimates of `delaynav replay
--out` with the onboard roll and pitch (trim taken off, as the replay does), as they are and with
the estimated horizontal bias put back into the tilt (`roll - b_y / g`, `pitch + b_x / g`, small
angles), over the replay's scored window.

    delaynav replay ../shared/data/ardupilot-log171/log171.bin --estimator proposed \\
        --out target/log171-estimates.csv
    python3 scripts/tilt-against-reference.py target/log171-estimates.csv \\
        ../shared/data/ardupilot-log171/ekf1_reference.csv [--from 85.2 --to 228.5 \\
        --trim-roll-rad 0.0205 --trim-pitch-rad 0.0053]

Prints, for roll and pitch, the mean and RMS of the difference (estimate minus onboard, degrees)
as estimated and with the bias put back. The defaults are log171's window and trim.
"""
import argparse
import bisect
import csv
import math

G = 9.80665


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("estimates", help="CSV of `delaynav replay --out` (one estimator)")
    p.add_argument("reference", help="onboard solution CSV (t_s, roll_deg, pitch_deg)")
    p.add_argument("--from", dest="t0", type=float, default=85.2, help="start of the window, s")
    p.add_argument("--to", dest="t1", type=float, default=228.5, help="end of the window, s")
    p.add_argument("--trim-roll-rad", type=float, default=0.0205)
    p.add_argument("--trim-pitch-rad", type=float, default=0.0053)
    a = p.parse_args()

    est = list(csv.DictReader(open(a.estimates)))
    if not est:
        raise SystemExit(f"{a.estimates}: no estimate")
    t_est = [int(r["t_us"]) * 1e-6 for r in est]

    def at(t, column):
        i = bisect.bisect_left(t_est, t)
        if i <= 0 or i >= len(t_est):
            return None
        w = (t - t_est[i - 1]) / (t_est[i] - t_est[i - 1])
        return float(est[i - 1][column]) * (1 - w) + float(est[i][column]) * w

    rows = {"roll": ([], []), "pitch": ([], [])}
    for r in csv.DictReader(open(a.reference)):
        t = float(r["t_s"])
        if not a.t0 <= t <= a.t1:
            continue
        roll, pitch = at(t, "roll_deg"), at(t, "pitch_deg")
        if roll is None:
            continue
        bx, by = at(t, "acc_bias_x_m_s2"), at(t, "acc_bias_y_m_s2")
        d_roll = roll - math.degrees(a.trim_roll_rad) - float(r["roll_deg"])
        d_pitch = pitch - math.degrees(a.trim_pitch_rad) - float(r["pitch_deg"])
        rows["roll"][0].append(d_roll)
        rows["roll"][1].append(d_roll - math.degrees(by / G))
        rows["pitch"][0].append(d_pitch)
        rows["pitch"][1].append(d_pitch + math.degrees(bx / G))
    n = len(rows["roll"][0])
    if n == 0:
        raise SystemExit("no reference sample inside the window and the estimates")

    def stats(v):
        return sum(v) / len(v), math.sqrt(sum(x * x for x in v) / len(v))

    print(f"{n} reference samples, {a.t0}-{a.t1} s; estimate minus onboard, degrees")
    print("axis   as estimated: mean   RMS   bias put back: mean   RMS")
    for axis, (plain, back) in rows.items():
        m0, r0 = stats(plain)
        m1, r1 = stats(back)
        print(f"{axis:<6} {m0:20.3f} {r0:5.3f} {m1:21.3f} {r1:5.3f}")


if __name__ == "__main__":
    main()
