"""Fleets: `delaynav.batch` in process, and the Dask example on a real
`LocalCluster` (a scheduler and two worker processes)."""

from __future__ import annotations

import importlib.util

import pytest

import delaynav
from conftest import LOGS, REPO, log_path


def shared_logs():
    return [str(log_path(name)) for name in LOGS]


def test_batch_gives_each_log_its_replay_summary():
    logs = shared_logs() + ["/nonexistent/log.bin"]
    rows = delaynav.batch(logs, workers=2)
    assert [r["file"] for r in rows] == logs
    assert rows[-1]["error"].startswith("cannot open /nonexistent/log.bin")
    for path, row in zip(logs[:-1], rows[:-1]):
        try:
            expected = delaynav.replay(path, traces=False).row()
        except delaynav.DelaynavError as err:
            assert row == {"file": path, "error": str(err)}
            continue
        assert row == expected
    with pytest.raises(ValueError, match="workers"):
        delaynav.batch(logs, workers=0)


def load_example():
    spec = importlib.util.spec_from_file_location("fleet_dask", REPO / "examples" / "fleet_dask.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_dask_local_cluster_gathers_one_table():
    pd = pytest.importorskip("pandas")
    distributed = pytest.importorskip("dask.distributed")
    fleet = load_example()
    logs = shared_logs()
    with distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
    ) as cluster, distributed.Client(cluster) as client:
        assert len(client.scheduler_info()["workers"]) == 2
        table = fleet.fleet_table(client, logs)
    assert isinstance(table, pd.DataFrame)
    assert list(table["file"]) == logs
    expected = pd.DataFrame(delaynav.batch(logs, workers=1))
    pd.testing.assert_frame_equal(table, expected)
    ok = table[table["error"].isna()]
    assert len(ok) >= 1 and ok["proposed.yaw_rms_deg"].notna().any()
