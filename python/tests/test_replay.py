"""`delaynav.replay` gives the command line's figures: the summary equals the
JSON of `delaynav replay LOG --json` on every shared log."""

from __future__ import annotations

import json
import subprocess

import numpy as np
import pytest

import delaynav
from conftest import LOGS, log_path


def cli_summary(cli, path, tmp_path, estimator):
    out = tmp_path / "summary.json"
    run = subprocess.run(
        [str(cli), "replay", str(path), "--estimator", estimator, "--json", str(out), "--quiet"],
        capture_output=True,
        text=True,
    )
    return run, (json.loads(out.read_text()) if out.exists() else None)


@pytest.mark.parametrize("name", list(LOGS))
@pytest.mark.parametrize("estimator", ["proposed", "all"])
def test_replay_summary_equals_the_command_line_json(cli, tmp_path, name, estimator):
    path = log_path(name)
    run, expected = cli_summary(cli, path, tmp_path, estimator)
    if expected is None:
        # The command refused the log: Python raises with the same message.
        with pytest.raises(delaynav.DelaynavError) as err:
            delaynav.replay(path, estimators=estimator)
        assert str(err.value) in run.stderr, (str(err.value), run.stderr)
        return
    r = delaynav.replay(path, estimators=estimator)
    # Parsed JSON on both sides: every figure to its last printed digit.
    assert r.summary == expected
    assert r.estimators == [e["estimator"] for e in expected["estimators"]]
    assert r.derived == expected["derived"]


def test_replay_arrays_on_log171():
    path = log_path("log171.bin")
    r = delaynav.replay(path, estimators=("proposed", "ekf16"), reference=True)
    assert r.estimators == ["proposed", "ekf16"]
    t = r.trace("proposed")
    n = len(t["t_us"])
    assert n > 5000
    assert np.all(np.diff(t["t_us"].astype(np.int64)) >= 0)
    for key, cols in [
        ("attitude", 4),
        ("euler_deg", 3),
        ("aligned_euler_deg", 3),
        ("position_ned_m", 3),
        ("velocity_ned_m_s", 3),
        ("covariance_diagonal", 16),
    ]:
        assert t[key].shape == (n, cols), key
        assert np.all(np.isfinite(t[key])), key
    assert np.allclose(np.linalg.norm(t["attitude"], axis=1), 1.0, atol=1e-9)
    # The delay's last value is the summary's final delay (when estimated).
    final = r.estimator("proposed")["final_delay_s"]
    if final is not None:
        assert t["delay_s"][-1] == pytest.approx(final, abs=1e-12)
    assert np.all(np.isnan(r.trace("ekf16")["delay_s"]))
    # The replayed window: from the warm-up to the summary's end.
    assert t["time_s"][-1] <= r.summary["to_s"] + 0.05
    assert t["time_s"][0] >= r.summary["replayed_from_s"] - 0.05
    assert r.reference is not None and r.reference.shape[1] == 4
    # The aligned yaw follows the onboard reference (the summary's RMS is a few degrees).
    assert r.estimator("proposed")["yaw_rms_deg"] < 20


def test_replay_protection_levels_follow_the_alert_limits():
    r = delaynav.replay(log_path("log171.bin"), estimators=("proposed", "ekf16"))
    for name in r.estimators:
        t = r.trace(name)
        n = len(t["t_us"])
        levels, valid = t["protection_levels"], t["valid"]
        assert levels.shape == (n, 6) and valid.shape == (n, 6), name
        assert valid.dtype == bool
        assert list(t["level_names"]) == [
            "tilt_deg", "heading_deg", "horizontal_m", "vertical_m", "velocity_m_s", "delay_s"]
        assert not np.any(np.isnan(levels)), name
        # A valid quantity is one whose level is within its alert limit, at every estimate.
        limits = r.config["ekf"]["integrity"]
        for i, key in enumerate(["tilt_alert_limit_deg", "heading_alert_limit_deg",
                                 "horizontal_alert_limit_m", "vertical_alert_limit_m",
                                 "velocity_alert_limit_m_s"]):
            assert np.all(levels[valid[:, i], i] <= limits[key] + 1e-9), (name, key)
    # The navigator: aligned most of the flight, its tilt valid at most estimates. Ekf16's tilt
    # level also carries what its unmodelled GPS latency turns the attitude by (the change of the
    # acceleration over the 0.4 s allowance): on this vibrating 50 Hz log it is the higher level
    # and the less often valid one.
    tilt = {name: r.trace(name)["protection_levels"][:, 0] for name in r.estimators}
    tilt_valid = {name: r.trace(name)["valid"][:, 0].mean() for name in r.estimators}
    assert tilt_valid["proposed"] > 0.5, tilt_valid
    assert tilt_valid["ekf16"] < tilt_valid["proposed"], tilt_valid
    assert np.median(tilt["ekf16"]) > np.median(tilt["proposed"])
    # The summary's levels at the scored samples.
    i = r.estimator("proposed")["integrity"]
    assert i["epochs"] > 1000 and 0.0 < i["availability"] <= 1.0
    assert 0.0 <= i["tilt_deg"]["exceeded_share"] <= 1.0


def test_to_pandas():
    pd = pytest.importorskip("pandas")
    r = delaynav.replay(log_path("log171.bin"))
    df = r.to_pandas()
    assert isinstance(df, pd.DataFrame)
    assert len(df) == len(r.time_s)
    assert {"roll_deg", "yaw_deg", "north_m", "vd_m_s", "delay_s", "delay_std_s"} <= set(df.columns)
    assert df.index.name == "time_s"


def test_a_config_dict_is_merged_like_the_config_file(cli, tmp_path):
    path = log_path("log171.bin")
    toml = tmp_path / "nav.toml"
    toml.write_text("[ekf]\naccel_noise_density = 0.1\n")
    out = tmp_path / "summary.json"
    subprocess.run(
        [str(cli), "replay", str(path), "--estimator", "proposed", "--config", str(toml),
         "--json", str(out), "--quiet"],
        check=True,
        capture_output=True,
    )
    r = delaynav.replay(path, config={"ekf": {"accel_noise_density": 0.1}})
    assert r.config["ekf"]["accel_noise_density"] == 0.1
    assert r.summary == json.loads(out.read_text())
    assert r.summary != delaynav.replay(path).summary


def test_a_missing_log_raises():
    with pytest.raises(delaynav.LogError, match="cannot open /nonexistent/log171.bin"):
        delaynav.replay("/nonexistent/log171.bin")


def test_bad_config_names_the_key_the_value_and_the_bound():
    path = log_path("log171.bin")
    with pytest.raises(delaynav.ConfigError) as err:
        delaynav.replay(path, config={"ekf": {"mag_gate": float("nan")}})
    assert "ekf.mag_gate" in str(err.value) and "NaN" in str(err.value)
    with pytest.raises(delaynav.ConfigError, match="no_such_key"):
        delaynav.replay(path, config={"ekf": {"no_such_key": 1.0}})
    with pytest.raises(delaynav.ConfigError, match="ekf.mag_gate"):
        delaynav.replay(path, config={"ekf": {"mag_gate": object()}})
    with pytest.raises(ValueError, match="estimator `nope` is unknown"):
        delaynav.replay(path, estimators=["nope"])
