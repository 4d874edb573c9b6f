"""The walk-through of docs/python.md as one script: replays log171, prints
its figures, and draws docs/python-log171.png (the attitude against the
autopilot's, the GPS delay with its sigma).

    python python/examples/walkthrough.py [LOG] [--png docs/python-log171.png]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

import delaynav

REPO = Path(__file__).resolve().parents[2]


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("log", nargs="?", default=str(REPO.parent / "shared/data/ardupilot-log171/log171.bin"))
    parser.add_argument("--png", default=str(REPO / "docs" / "python-log171.png"))
    args = parser.parse_args()

    # [1] Replay the log: the defaults come from the log itself.
    r = delaynav.replay(args.log, estimators=("proposed", "ekf16"), reference=True)
    for note in r.notes:
        print(note)
    proposed = r.estimator("proposed")
    print(f"final delay {proposed['final_delay_s']} s, yaw RMS {proposed['yaw_rms_deg']:.2f} deg")

    # [2] The estimates as a table.
    df = r.to_pandas("proposed")
    print(df[["roll_deg", "pitch_deg", "yaw_deg", "delay_s", "delay_std_s"]].describe().round(3))

    # [3] Plot: yaw of both estimators against the autopilot's, and the delay.
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax_yaw, ax_delay) = plt.subplots(2, 1, figsize=(9, 6), sharex=True)
    ref = r.reference
    ax_yaw.plot(ref[:, 0], ref[:, 3], "k", lw=1, label="autopilot (reference)")
    for name in r.estimators:
        t = r.trace(name)
        ax_yaw.plot(t["time_s"], t["aligned_euler_deg"][:, 2], lw=0.8, label=name)
    ax_yaw.set_ylabel("yaw, deg")
    ax_yaw.legend(loc="lower left", fontsize=8)
    t = r.trace("proposed")
    d, s = t["delay_s"], t["delay_std_s"]
    ax_delay.plot(t["time_s"], d, lw=1, label="delay estimate")
    ax_delay.fill_between(t["time_s"], d - s, d + s, alpha=0.3, label="1 sigma")
    ax_delay.set_ylabel("GPS delay, s")
    ax_delay.set_xlabel("time on the log's clock, s")
    ax_delay.axvspan(r.summary["replayed_from_s"], r.summary["scored_from_s"], color="0.9", label="warm-up")
    ax_delay.legend(loc="upper right", fontsize=8)
    fig.suptitle(f"{Path(args.log).name}: replayed from Python")
    fig.tight_layout()
    fig.savefig(args.png, dpi=80)
    print(f"plot written to {args.png}")
    assert np.isfinite(d[-1])


if __name__ == "__main__":
    main()
