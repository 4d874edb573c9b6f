"""Replays a fleet of logs on a Dask cluster and gathers one pandas table.

    python examples/fleet_dask.py LOG_OR_DIR... [--scheduler tcp://HOST:8786] [--out fleet.csv]

Without ``--scheduler`` a ``LocalCluster`` (a scheduler and two worker
processes) is started on this machine; with it the same code runs on that
cluster (every worker needs ``pip install ./python`` and the logs at the same
paths). Each task replays one log with the defaults derived from it
(``delaynav.replay``, the summary only) and returns one row
(``delaynav.summary_row``); a log that fails is a row with its ``error``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path


def replay_row(path: str, estimators: tuple[str, ...] = ("proposed",)) -> dict:
    """One log replayed on a worker: its table row, or its error."""
    import delaynav

    try:
        r = delaynav.replay(path, estimators=estimators, traces=False)
    except delaynav.DelaynavError as err:
        return {"file": path, "error": str(err)}
    return r.row()


def find_logs(inputs: list[str]) -> list[str]:
    """The `.bin` and `.ulg` files and CSV folders (holding `imu.csv`) named or under the folders named."""
    logs = []
    for given in map(Path, inputs):
        if given.is_file():
            logs.append(given)
            continue
        for p in sorted(given.rglob("*")):
            if p.suffix.lower() in (".bin", ".ulg"):
                logs.append(p)
        for imu in sorted(given.rglob("imu.csv")):
            logs.append(imu.parent)
    return [str(p) for p in logs]


def fleet_table(client, logs: list[str], estimators: tuple[str, ...] = ("proposed",)):
    """Submits one task per log to the Dask ``client`` and gathers the rows
    into one pandas DataFrame, in the order of ``logs``."""
    import pandas as pd

    futures = client.map(replay_row, logs, estimators=estimators, pure=False)
    return pd.DataFrame(client.gather(futures))


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("inputs", nargs="+", help="logs, or folders searched for logs")
    parser.add_argument("--scheduler", help="a Dask scheduler's address (default: a LocalCluster)")
    parser.add_argument("--workers", type=int, default=2, help="LocalCluster worker processes")
    parser.add_argument("--out", help="write the table as CSV")
    args = parser.parse_args(argv)

    from dask.distributed import Client, LocalCluster

    logs = find_logs(args.inputs)
    if not logs:
        print("no log found", file=sys.stderr)
        return 1
    if args.scheduler:
        client = Client(args.scheduler)
        cluster = None
    else:
        cluster = LocalCluster(n_workers=args.workers, threads_per_worker=1, processes=True)
        client = Client(cluster)
    try:
        table = fleet_table(client, logs)
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
    print(table.to_string())
    if args.out:
        table.to_csv(args.out, index=False)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
