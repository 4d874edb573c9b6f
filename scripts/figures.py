#!/usr/bin/env python3
"""Writes the manual's tables of figures from the committed JSON of docs/results/.

    python3 scripts/figures.py           rewrite every marked block
    python3 scripts/figures.py --check   exit 1 and print a diff when a file would change

A block is the text between `<!-- figures:begin NAME -->` and `<!-- figures:end NAME -->` in
README.md and docs/*.md (docs/journal/ is history, never rewritten). Each NAME has a renderer
below that reads docs/results/*.json (written by scripts/results.sh) and returns the block's
text, the command that made the JSON included. A block whose begin line carries
`hand-written: REASON` is left as it stands (its figures have no JSON). An unknown NAME, a
block without its end, or a missing JSON file is an error. Standard library only.
"""

import argparse
import difflib
import json
import pathlib
import re
import sys

ROOT = pathlib.Path(__file__).resolve().parent.parent
RESULTS = ROOT / "docs" / "results"
BEGIN = re.compile(r"^<!-- figures:begin (\S+)(?: (hand-written: .*))? -->$")
REPRO = "cargo run --release --features sim --example reproduce --"
REPLAY = "delaynav replay"  # cargo install --path cli
HAND_TUNED = "--accel-noise-density 0.05 --gyro-noise-density 0.005 --declination-deg 11.8"


def load(name):
    path = RESULTS / name
    if not path.exists():
        sys.exit(f"{path.relative_to(ROOT)} is missing: run scripts/results.sh")
    return json.loads(path.read_text())


# ---- number formats -------------------------------------------------------------------------


def rust_e(x, digits):
    """Rust's `{:.Ne}`: no `+` and no leading zero in the exponent."""
    mantissa, exp = f"{x:.{digits}e}".split("e")
    return f"{mantissa}e{int(exp)}"


def fmt_value(x):
    """delaynav::sim::suite::tables::fmt_value: 4 decimals from 0.01, else 3 significant digits."""
    if x is None:
        return "fail"
    if x == 0:
        return "0"
    return f"{x:.4f}" if abs(x) >= 0.01 else rust_e(x, 2)


def fmt_short(x):
    if x == 0:
        return "0"
    return f"{x:.3f}" if abs(x) >= 0.01 else rust_e(x, 1)


def fmt_ci(mean, ci):
    """delaynav::sim::suite::tables's fmt_ci: a mean and the half-width of its 95 % interval."""
    if mean is None:
        return "fail"
    if ci is None or ci[0] is None or ci[1] is None:
        return fmt_value(mean)
    half = 0.5 * (ci[1] - ci[0])
    if abs(half) <= 1e-9 * abs(mean):
        return fmt_value(mean)
    return f"{fmt_value(mean)} ±{fmt_short(half)}"


def fixed(x, digits, none="-"):
    return none if x is None else f"{x:.{digits}f}"


def thousands(x):
    return f"{int(x):,}"


def table(head, rows):
    lines = ["|" + "|".join(f" {c} " if c else " " for c in head) + "|", "|" + "---|" * len(head)]
    lines += ["|" + "|".join(f" {c} " if str(c) else " " for c in row) + "|" for row in rows]
    return lines


def sh(*commands):
    return ["```sh", *commands, "```"]


# ---- the simulator tables (reproduce) -------------------------------------------------------

# The Monte Carlo run's rows, in the order reproduce registers them.
MC_ORDER = ["bound", "bound_filter_heading", "bound_calibrated", "ekf16", "aekf17", "proposed",
            "calibrated", "oracle", "ekf16_f32", "aekf17_f32", "proposed_f32", "fusion_nav"]
# The paper's Table 6 (proposed, AEKF) per scenario: pitch, roll, yaw, velocity, position, delay.
PAPER_TABLE6 = {
    "low": [(0.059, 0.2237), (0.0616, 0.2868), (0.181, 0.3116), (0.0163, 0.0229),
            (0.381, 0.4462), (0.000678, 0.00396)],
    "high": [(0.0878, 1.1467), (0.1276, 0.8195), (0.1644, 1.0829), (0.0192, 0.0425),
             (0.0344, 0.4896), (0.000492, 0.00506)],
}
# The paper's Table 5 (EKF, proposed): gyro x, y, z (rad/s), accelerometer x, y, z (g).
PAPER_TABLE5 = [(0.000945, 0.000112), (0.000675, 0.000075), (0.000130, 0.000080),
                (0.055240, 0.009653), (0.057460, 0.006093), (0.043000, 0.005345)]
PAIRED_AGAINST = ["oracle", "aekf17", "ekf16", "calibrated"]
PAIRED_FIGURES = ["roll_deg", "pitch_deg", "yaw_deg", "tilt_deg", "heading_deg", "vel_m_s",
                  "pos_m"]
ACCEL_LIMIT = {"low": "19.61", "high": "50.45"}


def ordered(estimators, order):
    extra = sorted(set(estimators) - set(order))
    if extra:
        sys.exit(f"estimators without a place in the table: {extra}")
    return [n for n in order if n in estimators]


def lo_hi(doc):
    """The two scenarios, `low` then `high`."""
    by = {s["name"]: s for s in doc["scenarios"]}
    return by["low"], by["high"]


def pair(doc, get):
    low, high = lo_hi(doc)
    a, b = get(low), get(high)
    return f"{a} / {b}"


def est(scenario, name):
    return scenario["estimators"][name]


def nees(x):
    if x is None:
        return "-"
    return f"{x:.2f}" if x < 10 else f"{x:.1f}"


def where_it_stands():
    doc = load("results.json")
    rows = []
    for name in ["bound", "bound_filter_heading", "oracle", "proposed", "proposed_f32",
                 "calibrated", "aekf17", "ekf16", "fusion_nav"]:
        e = lambda s, k, n=name: est(s, n)[k]  # noqa: E731
        delay = "-" if est(doc["scenarios"][0], name)["delay_s"] is None or name == "oracle" \
            else pair(doc, lambda s: f"{e(s, 'delay_s') * 1e3:.2f}")
        rows.append([
            f"`{name}`",
            pair(doc, lambda s: fixed(e(s, "tilt_deg"), 3)),
            pair(doc, lambda s: fixed(e(s, "heading_deg"), 3)),
            pair(doc, lambda s: fixed(e(s, "vel_m_s"), 4)),
            pair(doc, lambda s: fixed(e(s, "pos_m"), 3)),
            delay,
            "-" if est(doc["scenarios"][0], name)["nees_mean"] is None or name == "bound"
            else pair(doc, lambda s: nees(e(s, "nees_mean"))),
        ])
    seeds = len(doc["seeds"])
    return [
        f"**Where it stands ({seeds} seeds).** Means over {seeds} seeds, `low` / `high`, from the "
        f"run of \"Monte Carlo:",
        f"{seeds} seeds\" (`{REPRO} --seeds {seeds} --json",
        "docs/results/results.json`):",
        "",
        *table(["row", "tilt (deg)", "heading (deg)", "velocity (m/s)", "position (m)",
                "delay RMSE (ms)", "NEES"], rows),
    ]


def calibrated():
    doc = load("results.json")
    rows = []
    for name in ["bound", "bound_calibrated", "proposed", "calibrated"]:
        e = lambda s, k, n=name: est(s, n)[k]  # noqa: E731
        rows.append([
            f"`{name}`",
            pair(doc, lambda s: fixed(e(s, "tilt_deg"), 3)),
            pair(doc, lambda s: fixed(e(s, "heading_deg"), 3)),
            pair(doc, lambda s: fixed(e(s, "vel_m_s"), 4)),
            pair(doc, lambda s: fixed(e(s, "pos_m"), 3)),
            pair(doc, lambda s: fixed(e(s, "accel_bias_g")[0], 4)),
            "-" if est(doc["scenarios"][0], name)["nees_mean"] is None or name.startswith("bound")
            else pair(doc, lambda s: nees(e(s, "nees_mean"))),
        ])
    return table(["row", "tilt (deg)", "heading (deg)", "velocity (m/s)", "position (m)",
                  "accel bias x (g)", "NEES"], rows)


def monte_carlo_20():
    doc = load("results.json")
    seeds = len(doc["seeds"])
    out = [
        f"Command and output (both scenarios, {seeds} seeds of {doc['duration_s']:g} s, seeds "
        f"{doc['seeds'][0]}-{doc['seeds'][-1]}; about 45 s on the shared 2-core",
        "machine with other jobs running, so the `µs per IMU sample` row compares rows of this "
        "run only):",
        "",
        *sh(f"{REPRO} --seeds {seeds} --json docs/results/results.json"),
    ]
    for s in lo_hi(doc):
        names = ordered(s["estimators"], MC_ORDER)
        ests = [s["estimators"][n] for n in names]
        floor = s["noise_floor"]
        out += [
            f"### `{s['name']}`: acceleration limit {ACCEL_LIMIT[s['name']]} m/s², true delay "
            f"{s['true_delay_s']:g} s; mean ±95 % t-interval over {seeds} seeds of the RMSE after "
            f"{doc['skip_s']:g} s of {doc['duration_s']:g} s",
            "",
        ]
        cal = s.get("calibrated_delay_s") or []
        if cal:
            out.append(
                "`proposed`, `calibrated` and `aekf17` start from an offline delay calibration on "
                "a separate 60 s run (seed + 10000): "
                + ", ".join(f"{d:.4f}" for d in cal)
                + f" s per seed, RMS error {s['calibration_rms_error_s'] * 1e3:.2f} ms")
        else:
            out.append("`proposed` and `aekf17` start from 0.3 s, uncalibrated")
        out.append("")
        out += [f"| RMSE | {' | '.join(names)} | paper proposed | paper AEKF | floor |",
                "|---|" + "---|" * len(names) + "---|---|---|"]
        paper = PAPER_TABLE6[s["name"]]
        tilt = fmt_value(floor["tilt_deg"])
        heading = f"{fmt_value(floor['heading_mag_only_deg'])} (mag only)"
        rows = [
            ("pitch (deg)", "pitch_deg", paper[0], tilt),
            ("roll (deg)", "roll_deg", paper[1], tilt),
            ("yaw (deg)", "yaw_deg", paper[2], heading),
            ("tilt (deg)", "tilt_deg", None, tilt),
            ("heading (deg)", "heading_deg", None, heading),
            ("velocity (m/s)", "vel_m_s", paper[3], fmt_value(floor["vel_m_s"])),
            ("position (m)", "pos_m", paper[4], fmt_value(floor["pos_m"])),
            ("delay (s)", "delay_s", paper[5], f"{fmt_value(s['delay_bound_s'])} (bound)"),
        ]
        for label, key, p, fl in rows:
            cells = ["-" if e[key] is None else fmt_ci(e[key], e[f"{key}_ci95"]) for e in ests]
            pp, pa = ("-", "-") if p is None else (fmt_value(p[0]), fmt_value(p[1]))
            out.append(f"| {label} | {' | '.join(cells)} | {pp} | {pa} | {fl} |")
        timing = " | ".join(f"{e['us_per_imu_sample']:.2f}" for e in ests)
        out.append(f"| µs per IMU sample | {timing} | | | |")
        medians = ", ".join(f"{n} {e['delay_s_median'] * 1e3:.2f}" for n, e in zip(names, ests)
                            if e["delay_s_median"] is not None)
        out += ["", f"Delay RMSE, median over the seeds (ms): {medians}", ""]
        out += [f"Bias RMSE (`{s['name']}`; the paper's Table 5 beside, scenario not stated "
                "there)", "",
                f"| bias | {' | '.join(names)} | paper EKF | paper proposed |",
                "|---|" + "---|" * len(names) + "---|---|"]
        labels = ["gyro x (rad/s)", "gyro y (rad/s)", "gyro z (rad/s)", "accel x (g)",
                  "accel y (g)", "accel z (g)"]
        for i, label in enumerate(labels):
            key, j = ("gyro_bias_rad_s", i) if i < 3 else ("accel_bias_g", i - 3)
            cells = [fmt_ci(e[key][j], e[f"{key}_ci95"][j]) for e in ests]
            pe, pp = PAPER_TABLE5[i]
            out.append(f"| {label} | {' | '.join(cells)} | {fmt_value(pe)} | {fmt_value(pp)} |")
        out += ["", f"Paired differences (`{s['name']}`): `proposed` minus each row on the same "
                "seeds, mean ±95 % t-interval; negative: `proposed` lower", "",
                f"| proposed minus | {' | '.join(PAIRED_FIGURES)} |",
                "|---|" + "---|" * len(PAIRED_FIGURES)]
        for other in PAIRED_AGAINST:
            p = s["paired"].get(f"proposed_minus_{other}")
            if p is not None:
                cells = [fmt_ci(p[f]["mean"], p[f]["ci95"]) for f in PAIRED_FIGURES]
                out.append(f"| {other} | {' | '.join(cells)} |")
        out += ["", f"Consistency (`{s['name']}`): NEES of [position, velocity] (6 dof, the "
                "filter's own covariance at the instant its estimate describes), every 100 ms, "
                "averaged over the seeds; GPS NIS (6 dof, diagonal of S) over every scored fix", "",
                "| estimator | NEES mean | NEES 95 % band | instants in band | NIS mean | NIS 95 % "
                "band |", "|---|---|---|---|---|---|"]
        for n, e in zip(names, ests):
            if e["nees_mean"] is None and e["nis_mean"] is None and e["nis_band95"][0] is None:
                continue
            nb, ib = e["nees_band95"], e["nis_band95"]
            out.append(f"| {n} | {fmt_value(e['nees_mean'])} | [{nb[0]:.2f}, {nb[1]:.2f}] | "
                       f"{100 * e['nees_in_band_fraction']:.0f} % | {fmt_value(e['nis_mean'])} | "
                       f"[{ib[0]:.2f}, {ib[1]:.2f}] |")
        out.append("")
    out.append("floor: steady-state error of an ideal filter with this noise at hover "
               "(docs/RESULTS.md); delay bound: RMS over the scored fixes of 1/sqrt(sum |a|²/σv²) "
               "over the last 5 s of fixes.")
    return out


# What each row of the bound study changes (descriptions, not figures).
BOUND_STUDY_ROWS = [
    ("bound", "nothing: whole field, the estimators' prior, the true noise"),
    ("bound_gps_prior", "the prior `bound` had before (heading 0.5 rad, position and velocity at "
     "the GPS noise)"),
    ("bound_filter_walks", "the bias random walks the filters are configured with (the "
     "simulator's biases are constant)"),
    ("bound_known_biases", "the biases known"),
    ("bound_heading_only", "a heading sensor instead of the field (the former "
     "`bound_heading_mag`)"),
    ("bound_filter_heading", "the field as the estimators take it: a tilt-compensated heading"),
    ("filter_gain", "that, with the estimators' heading-only gain once the tilt is known (not a "
     "bound)"),
    ("filter_gain_walks", "that, with their bias walks: the estimators' own model, linearized "
     "about the truth"),
    ("oracle", "(the navigator given the true delay)"),
    ("proposed", ""),
]


def bound_study():
    doc = load("bound-study.json")
    seeds = len(doc["seeds"])
    names = [n for n, _ in BOUND_STUDY_ROWS]
    ordered(doc["scenarios"][0]["estimators"], names)
    rows = []
    for name, what in BOUND_STUDY_ROWS:
        e = lambda s, k, n=name: est(s, n)[k]  # noqa: E731
        bias = lambda s, n=name: "0" if est(s, n)["accel_bias_g"][0] == 0 \
            else fixed(est(s, n)["accel_bias_g"][0], 4)  # noqa: E731
        rows.append([f"`{name}`", what,
                     pair(doc, lambda s: fixed(e(s, "tilt_deg"), 3)),
                     pair(doc, lambda s: fixed(e(s, "pitch_deg"), 3)),
                     pair(doc, lambda s: fixed(e(s, "heading_deg"), 3)),
                     pair(doc, lambda s: fixed(e(s, "vel_m_s"), 4)),
                     pair(doc, bias)])
    return [
        *sh(f"{REPRO} --seeds {seeds} --bound-study --json docs/results/bound-study.json"),
        "",
        f"(About 3 min on the shared 2-core machine.) Means over {seeds} seeds of "
        f"{doc['duration_s']:g} s, scored after {doc['skip_s']:g} s,",
        "`low` / `high`:",
        "",
        *table(["row", "what differs from `bound`", "tilt (deg)", "pitch (deg)", "heading (deg)",
                "velocity (m/s)", "accel bias x (g)"], rows),
    ]


SWEEP_COLUMNS = ["bound", "bound_filter_heading", "ekf16", "aekf17", "proposed", "oracle",
                 "proposed_f32", "fusion_nav"]


def sweep(name):
    doc = load(f"sweep-{name}.json")
    seeds = len(doc["seeds"])
    out = [*sh(f"{REPRO} --sweep {name} --seeds {seeds} --json docs/results/sweep-{name}.json "
               "--plots target/sweeps")]
    for k, scenario in enumerate(["low", "high"]):
        rows = []
        for point in doc["points"]:
            s = {x["name"]: x for x in point["run"]["scenarios"]}[scenario]
            bound_vel = s["estimators"]["bound"]["vel_m_s"]
            cells = []
            for n in SWEEP_COLUMNS:
                e = s["estimators"][n]
                cell = f"{e['tilt_deg']:.2f} / {e['vel_m_s']:.3f}"
                if e["vel_m_s"] is None or e["vel_m_s"] > doc["diverged_factor"] * bound_vel:
                    cell += " (diverged)"
                cells.append(cell)
            delay = s["estimators"]["proposed"]["delay_s"]
            rows.append([f"{point['value']:g}", *cells, fixed(delay * 1e3, 1)])
        out += ["", f"`{scenario}`, tilt (deg) / velocity (m/s), mean over {seeds} seeds; last "
                "column: `proposed` delay RMSE", "",
                *table([doc["parameter"], *SWEEP_COLUMNS, "delay RMSE (ms)"], rows)]
    return out


# What each fault does (descriptions, not figures), in the suite's order.
FAULTS = {
    "gps_outage_30s": "no GPS from 20 to 50 s",
    "gps_jump_100m": "one fix 100 m north at 30 s",
    "gps_position_step_50m": "positions 50 m north from 30 s on, velocity good",
    "gps_first_fix_glitch": "first fix 1000 km north",
    "gps_bad_accuracy": "NaN, inf, 0, -1, 1e12 accuracy in 10 % of fixes",
    "imu_rate_change": "1 kHz until 30 s, then 200 Hz",
    "imu_dropouts": "10 % of IMU samples dropped at random",
    "imu_jitter": "+-30 % jitter of the IMU period",
    "future_timestamp": "one IMU sample stamped 1 h ahead at 30 s",
    "time_backwards": "every clock back 1 s at 30 s; the caller resets when told",
    "mag_disturbance_60deg": "field turned 60 deg about down from 30 to 40 s",
    "mag_late": "first magnetometer sample 5 s after the first fix",
    "hard_iron": "hard-iron offset of 30 % of the field, body frame, not in the config",
    "inflight_start": "switched on at 12 s in a 15 m/s level turn, 20 deg bank, 2 m/s^2 RMS "
                      "vibration",
    "no_magnetometer": "no magnetometer at all, start on the ground",
    "no_magnetometer_inflight": "no magnetometer, switched on at 20 s in flight",
    "inflight_tilt_5s": "switched on at 20 s in flight, with the magnetometer",
    "mag_norm_disturbance": "field norm x1.3 (direction kept) from 30 to 32 s: a steel structure passed",
}


def faults():
    doc = load("faults.json")
    rows = []
    for r in doc["faults"]:
        if r["name"] not in FAULTS:
            sys.exit(f"fault `{r['name']}` has no description in scripts/figures.py")
        value = fixed(r["measured"], 3, "none")
        if "max_tilt_deg" in r:
            value += f" (tilt {fixed(r['max_tilt_deg'], 3, 'none')})"
        rows.append([r["name"], FAULTS[r["name"]], r["criterion"], value, f"{r['limit']:g}",
                     "pass" if r["passed"] else "**FAIL**"])
    return [*sh(f"{REPRO} --faults --json docs/results/faults.json"), "",
            *table(["name", "fault", "measured", "value", "limit", ""], rows)]


def faults_seeds():
    doc = load("faults-seeds.json")
    seeds = doc["seeds"]
    rows = []
    for r in doc["faults"]:
        cells = []
        for x in r["per_seed"]:
            cell = fixed(x, 3, "none")
            cells.append(cell if x is not None and x <= r["limit"] else f"**{cell}**")
        rows.append([r["name"], *cells, fixed(r["measured"], 3, "none"), f"{r['limit']:g}",
                     f"{r['passed_seeds']}/{len(seeds)}",
                     "pass" if r["passed"] else "**FAIL**"])
    first, last = seeds[0], seeds[-1]
    return [*sh(f"{REPRO} --faults --seed {first} --seeds {len(seeds)} "
                "--json docs/results/faults-seeds.json"), "",
            *table(["row", *(f"seed {s}" for s in seeds), "median", "limit", "seeds passed",
                    f"seeds {first}-{last}"], rows)]


def integrity():
    doc = load("integrity.json")
    rows = []
    for r in doc["integrity"]:
        limit = f">= {r['limit']:g}" if r["name"] == "availability_clean" else f"{r['limit']:g}"
        rows.append([r["name"], fixed(r["measured"], 4, "none"), limit,
                     "pass" if r["passed"] else "**FAIL**"])
    return [*sh(f"{REPRO} --integrity --json docs/results/integrity.json"), "",
            *table(["row", "measured", "limit", ""], rows)]


def integrity_stanford():
    doc = load("integrity.json")
    units = {"tilt": "deg", "heading": "deg", "horizontal": "m", "velocity": "m/s"}
    rows = []
    for q, unit in units.items():
        d = doc["stanford"][q]
        rows.append([f"{q} (AL {d['alert_limit']:g} {unit})", thousands(d["nominal"]),
                     thousands(d["misleading"]), thousands(d["hazardous"]),
                     thousands(d["unavailable"]), thousands(d["unavailable_misleading"])])
    return table(["quantity", "nominal", "misleading", "hazardous", "unavailable",
                  "unavailable, error above PL"], rows)


# What each row of the delay suite tests (descriptions), the digits of its figure, and what
# follows its bound. A row with a bound is judged on its ratio to the bound (its limit).
DELAY_SUITE = {
    "cold_start_low": ("low scenario, delay RMSE (ms)", 2, ""),
    "cold_start_high": ("high scenario, delay RMSE (ms)", 2, ""),
    "delay_step": ("0.2 -> 0.35 s at 20 s, calibrated start: s until the error stays <= 10 ms",
                   2, ""),
    "delay_ramp": ("0.20 -> 0.26 s over 60 s, delay RMSE (ms)", 2, " (a line)"),
    "delay_ramp_coverage": ("the ramp's runs from 20 s: share within 1-sigma", 3, ""),
    "delay_jitter": ("+-20 ms uniform per fix, delay RMSE (ms)", 2, ""),
    "gps_2hz": ("2 Hz GPS, the loop's defaults, delay RMSE (ms)", 2, ""),
    "gps_1hz": ("1 Hz GPS, the loop's defaults, delay RMSE (ms)", 2, ""),
    "gps_rate_drop": ("GPS 10 Hz, 1 Hz from 30 s: delay RMSE from 40 s (ms)", 2, ""),
    "negative_delay": ("true -0.15 s, range -0.5..0.6 s, delay RMSE (ms)", 2, ""),
    "out_of_range_reported": ("true -0.15 s, default range: s until `BelowRange`", 2, ""),
    "out_of_range_weak": ("low, velocity noise doubled, true -0.15 s: s until `BelowRange`", 2,
                          ""),
    "sigma_coverage": ("low + high, 20 seeds, calibrated, from 10 s: share within 1-sigma", 3,
                       ""),
    "gentle_motion": ("ground vehicle, 2 m/s^2 peak, true 0.15 s: delay RMSE from 60 s (ms)", 2,
                      ""),
    "acquisition_sigma": ("cold_start_high, first valid update to `Locked`: median sigma / error",
                          2, ""),
    "valid_means_close": ("runs in range: share of `delay_valid` samples beyond 3 sigma", 4, ""),
    "aekf17_hover": ("AEKF17, 60 s hover: final error / sigma", 4, ""),
}


def delay_suite():
    five, twenty = load("delay-suite.json"), load("delay-suite-20.json")
    by20 = {r["name"]: r for r in twenty["delay_scenarios"]}
    rows = []
    for r in five["delay_scenarios"]:
        if r["name"] not in DELAY_SUITE:
            sys.exit(f"delay-suite row `{r['name']}` has no description in scripts/figures.py")
        what, digits, after = DELAY_SUITE[r["name"]]
        r20 = by20.get(r["name"], {"measured": None, "passed": False})
        lim = r["limit"]
        limit = f"{lim[0]:.2f}-{lim[1]:.2f}" if isinstance(lim, list) else f"{lim:g}"
        bound = r.get("bound", five["information_bounds"].get(r["name"]))
        if r.get("ratio") is not None:
            limit = f"{limit}x bound"
        passed = r["passed"] and r20["passed"]

        def figure(row):
            value = fixed(row["measured"], digits, "none")
            return value if row.get("ratio") is None else f"{value} ({row['ratio']:.2f}x)"
        rows.append([r["name"], what, limit, figure(r), figure(r20),
                     "" if bound is None else f"{bound:.2f}{after}",
                     "passes" if passed else "**fails**"])
    return [*sh(f"{REPRO} --delay-suite --json docs/results/delay-suite.json",
                f"{REPRO} --delay-suite --seeds {len(twenty['seeds'])} "
                "--json docs/results/delay-suite-20.json"), "",
            *table(["row", "what it tests", "limit", f"{len(five['seeds'])} seeds",
                    f"{len(twenty['seeds'])} seeds", "bound", "verdict"], rows)]


CORTEX_M4 = ["nav_estimated_f32", "nav_fixed_f32", "ekf16_f32", "aekf17_f32"]


def cortex_m4():
    doc = load("cortex-m4.json")
    rows = []
    for name in CORTEX_M4:
        e = doc["estimators"][name]
        rows.append([f"`{name}`", thousands(e["instructions_per_imu_sample_mean"]),
                     thousands(e["instructions_per_imu_sample_max"]),
                     f"{thousands(e['instructions_push_gps_mean'])} / "
                     f"{thousands(e['instructions_push_gps_max'])}",
                     thousands(e["size_of_bytes"]),
                     f"{thousands(e['stack_peak_construct_bytes'])} / "
                     f"{thousands(e['stack_peak_push_bytes'])}"])
    alone = doc.get("nav_only_image", {})
    for name, e in alone.get("estimators", {}).items():
        rows.append([f"`{name}`, alone in its image", thousands(e["instructions_per_imu_sample_mean"]),
                     thousands(e["instructions_per_imu_sample_max"]),
                     f"{thousands(e['instructions_push_gps_mean'])} / "
                     f"{thousands(e['instructions_push_gps_max'])}",
                     thousands(e["size_of_bytes"]),
                     f"{thousands(e['stack_peak_construct_bytes'])} / "
                     f"{thousands(e['stack_peak_push_bytes'])}"])
    flash = f"Flash {thousands(doc['flash_bytes'])} bytes"
    if alone.get("flash_bytes") is not None:
        flash += f" ({thousands(alone['flash_bytes'])} for the image that holds the navigator alone)"
    return [*sh("benches/cortex-m4/run --json docs/results/cortex-m4.json --check"), "",
            *table(["estimator", "per IMU sample, mean", "max", "`push_gps` mean / max",
                    "`size_of`", "stack, construction / pushes"], rows),
            f"{flash}."]


def cortex_m4_limits():
    doc = load("cortex-m4.json")
    limits = json.loads((ROOT / "benches" / "cortex-m4" / "limits.json").read_text())
    (name, lim), = limits["estimators"].items()
    e = doc["estimators"][name]
    keys = ["instructions_per_imu_sample_mean", "instructions_per_imu_sample_max",
            "size_of_bytes", "stack_peak_bytes"]
    ratio = limits["ratios"][0]
    r = (doc["estimators"][ratio["numerator"]][ratio["figure"]]
         / doc["estimators"][ratio["denominator"]][ratio["figure"]])
    (alone_name, alone_lim), = limits["nav_only_image"]["estimators"].items()
    alone = doc["nav_only_image"]["estimators"][alone_name]
    holds = (all(e[k] <= lim[k] for k in keys) and r >= ratio["min"]
             and all(alone[k] <= alone_lim[k] for k in alone_lim))
    enforced = not any(lim.get("not_enforced", []))
    if not (holds and enforced):
        sys.exit("a Cortex-M4 limit does not hold or is not enforced: reword the "
                 "`cortex-m4-limits` block of docs/PERFORMANCE.md and its renderer")
    v = [thousands(e[k]) for k in keys]
    m = [thousands(lim[k]) for k in keys]
    return [
        "**Every limit holds and is enforced by CI** (`limits.json` has no `not_enforced` entry): "
        "mean",
        f"instructions per IMU sample {v[0]} (limit {m[0]}), worst sample {v[1]} ({m[1]}), "
        f"`size_of` {v[2]} B",
        f"({m[2]}), stack peak {v[3]} B ({m[3]}; {thousands(alone['stack_peak_bytes'])} B in an image "
        f"that holds the navigator alone, limit {thousands(alone_lim['stack_peak_bytes'])}),",
        f"AEKF17 / proposed {r:.2f} (>= {ratio['min']:.1f}).",
    ]


def readme_cortex_m4():
    doc = load("cortex-m4.json")
    e = doc["estimators"]["nav_estimated_f32"]
    alone = doc["nav_only_image"]["estimators"]["nav_estimated_f32"]
    mean = e["instructions_per_imu_sample_mean"]
    return [
        f"At a 0.5 s maximum delay and 1 kHz IMU the navigator takes {thousands(e['size_of_bytes'])} B of "
        f"RAM, {e['stack_peak_construct_bytes'] / 1000:.1f} KB of stack to configure and",
        f"{e['stack_peak_push_bytes'] / 1000:.1f} KB to run ({alone['stack_peak_push_bytes'] / 1000:.1f} KB "
        "in a firmware that holds it alone), and about "
        f"{thousands(round(mean, -2))} instructions per IMU sample",
        f"on average ({thousands(e['instructions_per_imu_sample_max'])} at most) in QEMU "
        "([docs/PERFORMANCE.md](docs/PERFORMANCE.md)).",
    ]

# ---- the log171 replays (replay) ------------------------------------------------------------

REPLAY_ORDER = ["proposed", "aekf17", "ekf16"]


def replay_doc(name):
    """A replay's JSON: its estimators by name."""
    doc = load(name)
    by = {e["estimator"]: e for e in doc["estimators"]}
    ordered(by, REPLAY_ORDER)
    return by


def tuning_output():
    by = replay_doc("log171-log-derived.json")
    line = "{:<9} {:>9} {:>9} {:>9} {:>9} {:>10} {:>8} {:>8}"
    out = ["```text", line.format("estimator", "delay_s", "roll_deg", "pitch_deg", "yaw_deg",
                                  "vel_m_s", "refused", "nonfin")]
    for n in REPLAY_ORDER:
        e = by[n]
        out.append(line.format(n, *(fixed(e[k], 3) for k in (
            "final_delay_s", "roll_rms_deg", "pitch_rms_deg", "yaw_rms_deg",
            "velocity_rms_m_s")), e["samples_refused"], e["non_finite_estimates"]))
    h = by["proposed"]["health"]
    listed = lambda m: ", ".join(f"{k} {v}" for k, v in m.items()) or "none"  # noqa: E731
    out.append("proposed")
    for label, value in [("alignment", h["alignment"]), ("refused", listed(h["refused"])),
                         ("gated", listed(h["gated"])), ("resets", listed(h["resets"])),
                         ("last reset", h["last_reset"] or "none"),
                         ("delay", h["delay_status"])]:
        if value is not None:
            out.append(f"  {label:<10} {value}")
    return out + ["```"]


def gps_resets(e):
    """GPS block resets (position + velocity) of the health summary."""
    return sum(v for k, v in e["health"]["resets"].items() if "gps" in k)


def tuning_configs():
    window = load("log171-log-derived.json")["window_s"]
    out = [
        "RMS differences from the onboard EKF over the flight window "
        f"({window[0]:.1f}-{window[1]:.1f} s), final delay, GPS fixes",
        "with a block gated against position blocks fused, and GPS block resets (position + "
        "velocity), one",
        "run each:",
        "",
        *sh(f"{REPLAY} ../shared/data/ardupilot-log171/log171.bin --json target/log171.json "
            "[FLAGS]"),
        "",
    ]
    rows = []
    for config, name in [("log-derived", "log-derived"), ("hand-tuned", "hand-tuned"),
                         ("simulator defaults", "sim-defaults")]:
        by = replay_doc(f"log171-{name}.json")
        for n in REPLAY_ORDER:
            e = by[n]
            rows.append([config, n, *(fixed(e[k], 3) for k in (
                "roll_rms_deg", "pitch_rms_deg", "yaw_rms_deg", "velocity_rms_m_s",
                "final_delay_s")), f"{e['gps_gated']} / {e['gps_position_fused']}",
                gps_resets(e)])
    return out + table(["config", "estimator", "roll °", "pitch °", "yaw °", "velocity m/s",
                        "final delay s", "fixes gated / fused", "GPS resets"], rows)


def replay_no_flag():
    by = replay_doc("log171-log-derived.json")
    rows = [[n, *(fixed(by[n][k], 3) for k in ("final_delay_s", "roll_rms_deg", "pitch_rms_deg",
                                               "yaw_rms_deg", "velocity_rms_m_s"))]
            for n in REPLAY_ORDER]
    return [
        "`replay log171.bin` with no other flag, with the defaults derived from the log (below); "
        "the same",
        "command on the CSV folder prints the same figures to the digit (one run each):",
        "",
        *sh(f"{REPLAY} ../shared/data/ardupilot-log171/log171.bin --json out.json",
            f"{REPLAY} ../shared/data/ardupilot-log171 --json out.json"),
        "",
        *table(["estimator", "delay s", "roll °", "pitch °", "yaw °", "velocity m/s"], rows),
    ]


TABLE7_ADDED = ["0", "0.1", "0.2", "0.3"]
TABLE7_CMD = [
    f"{REPLAY} ../shared/data/ardupilot-log171 \\",
    "    --from 75 --to 225 --estimator all --add-gps-delay S --json out.json \\",
    f"    {HAND_TUNED}",
]


def replay_levels():
    by = replay_doc("log171-log-derived.json")
    pct = lambda x: "-" if x is None else f"{100 * x:.1f} %"
    level = lambda l, digits: "inf" if l["median_level"] is None else f"{l['median_level']:.{digits}f}"
    rows = []
    for n in REPLAY_ORDER:
        i = by[n]["integrity"]
        rows.append([f"`{n}`", thousands(i["epochs"]), pct(i["availability"]),
                     f"{level(i['tilt_deg'], 2)} / {pct(i['tilt_deg']['valid_share'])} / "
                     f"{pct(i['tilt_deg']['exceeded_share'])}",
                     f"{level(i['heading_deg'], 2)} / {pct(i['heading_deg']['valid_share'])} / "
                     f"{pct(i['heading_deg']['exceeded_share'])}",
                     f"{level(i['velocity_m_s'], 2)} / {pct(i['velocity_m_s']['valid_share'])} / "
                     f"{pct(i['velocity_m_s']['exceeded_share'])}",
                     f"{level(i['horizontal_m'], 2)} / {pct(i['horizontal_m']['valid_share'])}"])
    return table(["estimator", "epochs", "all valid", "tilt: level deg / valid / exceeded",
                  "heading: level deg / valid / exceeded", "velocity: level m/s / valid / exceeded",
                  "horizontal: level m / valid"], rows)


def replay_no_mag_sentence():
    nm = replay_doc("log171-no-mag.json")["proposed"]
    wm = replay_doc("log171-with-mag-from-114.json")["proposed"]
    w = load("log171-no-mag.json")["window_s"]
    return [f"On log171 from 30 s after the take-off (`{REPLAY} log171.bin --estimator proposed "
            f"--from 114.668 --no-mag`, scored {w[0]:.1f}-{w[1]:.1f} s, the replay starting at the "
            f"take-off after its 30 s warm-up), `proposed` has a yaw RMS of "
            f"{nm['yaw_rms_deg']:.3f} deg against the onboard EKF without the magnetometer, "
            f"{wm['yaw_rms_deg']:.3f} deg with it."]


def replay_hand_tuned():
    rows = []
    for added in ["0", "0.3"]:
        by = replay_doc(f"log171-table7-{added}.json")
        for n in REPLAY_ORDER:
            e = by[n]
            rows.append([n, "0" if added == "0" else f"{added} s",
                         fixed(e["final_delay_s"], 3, "–"),
                         *(fixed(e[k], 3) for k in ("roll_rms_deg", "pitch_rms_deg",
                                                    "yaw_rms_deg", "velocity_rms_m_s")),
                         f"{e['gps_gated']} / {e['gps_position_fused']}"])
    return [
        "The hand-tuned config of [TUNING.md](TUNING.md), replayed from 45 s, scored 75–225 s "
        "against",
        "`ekf1_reference.csv` (trim applied), without and with 0.3 s added to the GPS, one run "
        "each (the",
        "`.bin` gives the same figures as the folder):",
        "",
        *sh(*TABLE7_CMD),
        "",
        *table(["estimator", "added", "final delay (s)", "roll RMS (°)", "pitch RMS (°)",
                "yaw RMS (°)", "velocity RMS (m/s)", "GPS fixes gated / position blocks fused"],
               rows),
    ]


# The paper's Table 7 (final delay, s, and its change), as printed there.
PAPER_TABLE7 = {
    "0": ("0.326", "–", "0.352", "–"),
    "0.1": ("0.419", "0.093", "0.438", "0.086"),
    "0.2": ("0.521", "0.195", "0.569", "0.215"),
    "0.3": ("0.623", "0.297", "0.610", "0.258"),
}


def flight_log_table7():
    runs = {d: replay_doc(f"log171-table7-{d}.json") for d in TABLE7_ADDED}
    delays, accuracy = [], []
    for d in TABLE7_ADDED:
        cells = [d]
        for n, paper in [("proposed", PAPER_TABLE7[d][:2]), ("aekf17", PAPER_TABLE7[d][2:])]:
            final = runs[d][n]["final_delay_s"]
            change = "–" if d == "0" else f"{final - runs['0'][n]['final_delay_s']:.3f}"
            cells += [f"{final:.3f}", change, *paper]
        delays.append(cells)
        accuracy.append([d, *(
            f"{fixed(e['roll_rms_deg'], 2)} / {fixed(e['pitch_rms_deg'], 2)} / "
            f"{fixed(e['yaw_rms_deg'], 2)}, {fixed(e['velocity_rms_m_s'], 2)}, {e['gps_gated']}"
            for e in (runs[d][n] for n in REPLAY_ORDER))])
    fixes = runs["0"]["proposed"]["gps_position_fused"]
    return [
        *sh("for d in 0 0.1 0.2 0.3; do",
            f"  {REPLAY} ../shared/data/ardupilot-log171 \\",
            "      --from 75 --to 225 --estimator all --add-gps-delay $d --json table7-$d.json \\",
            f"      {HAND_TUNED}",
            "done"),
        "",
        "Final delay estimate at 225 s, and its change from the unaltered log:",
        "",
        *table(["added (s)", "proposed (s)", "change", "paper, proposed (s)", "change",
                "aekf17 (s)", "change", "paper, AEKF (s)", "change"], delays),
        "",
        "Accuracy against the onboard EKF in the same runs (roll / pitch / yaw RMS in degrees, "
        "velocity RMS",
        f"in m/s, GPS fixes gated of about {round(fixes, -1)}):",
        "",
        *table(["added (s)", "proposed", "aekf17", "ekf16 (no delay handling)"], accuracy),
    ]


def flight_log_step():
    by = replay_doc("log171-step.json")
    rows = []
    for n in ["proposed", "aekf17"]:
        st = by[n]["delay_step"]
        off = (st["final_s"] - st["target_s"]) * 1e3
        settled = st["settled_after_s"]
        rows.append([n, f"{st['before_s']:.3f} s", f"{st['reference_s']:.3f} s",
                     f"{st['final_s']:.3f} s", f"{st['target_s']:.3f} s",
                     f"{off:.1f} ms" if abs(off) < 100 else f"{off:.0f} ms",
                     "never" if settled is None else f"{settled:.1f} s"])
    return [
        *sh(f"{REPLAY} ../shared/data/ardupilot-log171 \\",
            "    --from 75 --to 225 --estimator all --add-gps-delay 0.2 --add-delay-from 150 "
            "--json step.json \\",
            f"    {HAND_TUNED} \\",
            "    --quiet --delay-windows step.csv"),
        "",
        *table(["estimator", "before (150 s)", "final without", "final with the step", "target",
                "off", "settled after"], rows),
    ]


# ---- the navigator's members (src/nav/memory.rs) --------------------------------------------

# The test's member names, in the table's order, and what the manual calls them.
NAV_MEMORY = [
    ("delay_loop", "delay loop (of which its `SlidingCorrelator<f32, 125, 31, 192>`: {corr})"),
    ("history (and its header cache)", "IMU history (16-bit block floating point, and its "
     "header cache)"),
    ("forward (output predictor)", "output predictor (`forward`, 39 entries)"),
    ("ekf", "`Ekf16` (the horizon filter)"),
    ("times", "sample times (16-bit steps with checkpoints)"),
    ("mags", "magnetometer queue (32 entries)"),
    ("whitening (accelerometer, gyroscope)", "whitening (accelerometer, gyroscope)"),
    ("config", "configuration"),
    ("last_update", "last delay update"),
    ("deltas", "deltas"),
]


def parse_nav_memory(text):
    """The JSON of the memory test's printed lines (`name: N B`)."""
    members, doc = {}, {}
    for line in text.splitlines():
        # The harness prints `test NAME ... ` before the test's first line.
        line = re.sub(r"^test \S+ \.\.\. ", "", line)
        # tests/nav_alloc.rs's memory_footprint: the default history and HIST=256.
        m = re.match(r"^DelayCompensatedNav<f32>: (\d+) B, <f64>: (\d+) B$", line)
        if m:
            doc["default_hist_bytes"] = {"f32": int(m.group(1)), "f64": int(m.group(2))}
            continue
        m = re.match(r"^HIST=256: f32 (\d+) B, f64 (\d+) B$", line)
        if m:
            doc["hist_256_bytes"] = {"f32": int(m.group(1)), "f64": int(m.group(2))}
            continue
        m = re.match(r"^(\s*)(.+?): (\d+) B$", line)
        if not m:
            continue
        name, value = m.group(2), int(m.group(3))
        if name.startswith("of which the delay loop's SlidingCorrelator"):
            doc["sliding_correlator_bytes"] = value
        elif name == "other members":
            doc["other_members_bytes"] = value
        elif name.startswith("DelayCompensatedNav<"):
            doc["type"], doc["total_bytes"] = name, value
        else:
            members[name] = value
    missing = {n for n, _ in NAV_MEMORY} - set(members)
    for key in ["total_bytes", "default_hist_bytes", "hist_256_bytes"]:
        missing |= set() if key in doc else {key}
    if missing:
        sys.exit(f"the memory tests printed no figure for {sorted(missing)}")
    doc["members_bytes"] = members
    return doc


def nav_memory():
    doc = load("nav-memory.json")
    m = doc["members_bytes"]
    rows = [[label.format(corr=thousands(doc["sliding_correlator_bytes"])), thousands(m[name])]
            for name, label in NAV_MEMORY]
    rows += [["other members", thousands(doc["other_members_bytes"])],
             ["**total**", f"**{thousands(doc['total_bytes'])}**"]]
    return [*sh("cargo test --all-features --lib nav::memory -- --nocapture"), "",
            *table(["member", "B"], rows)]


def nav_footprint():
    doc = load("nav-memory.json")
    m4 = load("cortex-m4.json")["estimators"]["nav_estimated_f32"]["size_of_bytes"]
    d, h = doc["default_hist_bytes"], doc["hist_256_bytes"]
    return table(["`HIST`", "use", "f32", "f64"], [
        ["1100 (default)", "1 kHz, delay range 0-1 s", f"{thousands(d['f32'])} B",
         f"{thousands(d['f64'])} B"],
        ["530", "1 kHz, 0-0.5 s (the Cortex-M4 limits)",
         f"{thousands(doc['total_bytes'])} B (Cortex-M4: {thousands(m4)})", "-"],
        ["256", "200 Hz, 0-1 s (or 1 kHz, 0-0.24 s)", f"{thousands(h['f32'])} B",
         f"{thousands(h['f64'])} B"],
    ])


KIND_NAMES = [("module", "modules"), ("struct", "structs"), ("enum", "enums"), ("trait", "traits"),
              ("function", "functions"), ("constant", "constants"), ("type_alias", "type aliases"),
              ("method", "methods"), ("assoc_const", "associated constants")]


def public_api():
    doc, hidden = load("public-api.json"), load("public-api-hidden.json")
    kinds = ", ".join(f"{doc['by_kind'].get(k, 0)} {name}" for k, name in KIND_NAMES)
    return ["Counted with `scripts/public-api.py` on rustdoc's JSON (default features), the command "
            f"in its header: {doc['total']} public items ({kinds}), and "
            f"{hidden['total'] - doc['total']} more under `internals` (counted with rustdoc's "
            f"`--document-hidden-items`: {hidden['total']})."]


RENDERERS = {
    "public-api": public_api,
    "where-it-stands": where_it_stands,
    "calibrated": calibrated,
    "monte-carlo-20": monte_carlo_20,
    "bound-study": bound_study,
    "sweep-gps_rate": lambda: sweep("gps_rate"),
    "sweep-imu_rate": lambda: sweep("imu_rate"),
    "sweep-delay": lambda: sweep("delay"),
    "faults": faults,
    "faults-seeds": faults_seeds,
    "integrity": integrity,
    "integrity-stanford": integrity_stanford,
    "delay-suite": delay_suite,
    "cortex-m4": cortex_m4,
    "readme-cortex-m4": readme_cortex_m4,
    "cortex-m4-limits": cortex_m4_limits,
    "tuning-log171-output": tuning_output,
    "tuning-log171-configs": tuning_configs,
    "replay-log171-no-flag": replay_no_flag,
    "replay-log171-hand-tuned": replay_hand_tuned,
    "replay-log171-levels": replay_levels,
    "replay-log171-no-mag": replay_no_mag_sentence,
    "flight-log-table7": flight_log_table7,
    "flight-log-step": flight_log_step,
    "nav-memory": nav_memory,
    "nav-footprint": nav_footprint,
}


# ---- the blocks -----------------------------------------------------------------------------


def files():
    yield ROOT / "README.md"
    yield from sorted((ROOT / "docs").glob("*.md"))


def render(path, text):
    """The file's text with every block rewritten; the names of the blocks seen."""
    lines = text.split("\n")
    out, seen, i = [], [], 0
    while i < len(lines):
        line = lines[i]
        out.append(line)
        m = BEGIN.match(line)
        i += 1
        if not m:
            continue
        name, hand = m.group(1), m.group(2)
        end = f"<!-- figures:end {name} -->"
        try:
            j = lines.index(end, i)
        except ValueError:
            sys.exit(f"{path.relative_to(ROOT)}: `{line}` without `{end}`")
        if hand:
            out += lines[i:j]
        elif name in RENDERERS:
            out += RENDERERS[name]()
        else:
            sys.exit(f"{path.relative_to(ROOT)}: no renderer for block `{name}` "
                     "(add one to scripts/figures.py or mark it `hand-written: REASON`)")
        seen.append((name, "hand-written" if hand else "rendered"))
        out.append(end)
        i = j + 1
    return "\n".join(out), seen


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--check", action="store_true",
                    help="change nothing; exit 1 with a diff when a file would change")
    ap.add_argument("--list", action="store_true", help="list the blocks and what they are")
    ap.add_argument("--parse-nav-memory", metavar="JSON", type=pathlib.Path,
                    help="write the JSON of src/nav/memory.rs's printed test output (stdin)")
    args = ap.parse_args()
    if args.parse_nav_memory:
        doc = parse_nav_memory(sys.stdin.read())
        args.parse_nav_memory.write_text(json.dumps(doc, indent=2, sort_keys=True) + "\n")
        return 0
    changed = []
    for path in files():
        text = path.read_text()
        new, seen = render(path, text)
        rel = path.relative_to(ROOT)
        if args.list:
            for name, how in seen:
                print(f"{rel}: {name} ({how})")
        if new == text:
            continue
        changed.append(rel)
        if args.check:
            sys.stdout.writelines(difflib.unified_diff(
                text.splitlines(True), new.splitlines(True), f"a/{rel}", f"b/{rel}"))
        else:
            path.write_text(new)
            print(f"rewrote {rel}")
    if args.check and changed:
        print(f"\n{len(changed)} file(s) differ from docs/results/*.json: run "
              "`python3 scripts/figures.py` (figures) or `scripts/results.sh` (new runs)",
              file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
