"""The streaming `delaynav.Navigator` matches the Rust navigator sample by
sample (the `stream` example writes the Rust side), its array variant matches
its sample-by-sample calls, and bad input raises, never crashes."""

from __future__ import annotations

import subprocess

import numpy as np
import pytest

import delaynav
from conftest import log_path

CONFIG = {"imu_rate_hz": 50.0, "ekf": {"mag_declination_rad": 0.2}}
CONFIG_TOML = "imu_rate_hz = 50.0\n[ekf]\nmag_declination_rad = 0.2\n"


def flatten(e, t_us):
    if e is None:
        return [float(t_us)] + [np.nan] * 34
    nan = np.nan
    return (
        [float(e["t_us"])]
        + list(e["attitude"])
        + list(e["position_ned_m"])
        + list(e["velocity_ned_m_s"])
        + list(e["accel_bias_m_s2"])
        + list(e["gyro_bias_rad_s"])
        + list(e["covariance_diagonal"])
        + [nan if e["delay_s"] is None else e["delay_s"], nan if e["delay_std_s"] is None else e["delay_std_s"]]
    )


def stream_in_python(log, config, count_imu_only=False):
    """Every record pushed one call at a time, in the reader's order; the
    estimate after each IMU sample."""
    nav = delaynav.Navigator(config)
    imu, gps, mag = log["imu"], log["gps"], log["mag"]
    k = {0: 0, 1: 0, 2: 0}
    rows, refused = [], 0
    for kind in log["order"]:
        i = k[kind]
        k[kind] += 1
        try:
            if kind == 0:
                nav.push_imu(int(imu["t_us"][i]), imu["gyro_rad_s"][i], imu["accel_m_s2"][i])
            elif kind == 1:
                acc = [None if np.isnan(a) else float(a) for a in gps["accuracy"][i]]
                lat, lon, alt = gps["geodetic"][i]
                if np.isnan(lat):
                    nav.push_gps_ned(int(gps["t_us"][i]), gps["position_ned_m"][i], gps["velocity_ned_m_s"][i], *acc)
                else:
                    nav.push_gps(int(gps["t_us"][i]), lat, lon, alt, gps["velocity_ned_m_s"][i], *acc)
            else:
                nav.push_mag(int(mag["t_us"][i]), mag["field_body"][i])
        except delaynav.SampleError:
            refused += kind == 0 or not count_imu_only
        if kind == 0:
            rows.append(flatten(nav.estimate(), imu["t_us"][i]))
    return nav, np.array(rows), refused


@pytest.mark.parametrize("name", ["log171.bin", "sample_px4_events.ulg"])
def test_streaming_navigator_matches_the_rust_one_sample_by_sample(stream_example, tmp_path, name):
    path = log_path(name)
    config = tmp_path / "nav.toml"
    config.write_text(CONFIG_TOML)
    out = tmp_path / "estimates.csv"
    subprocess.run(
        [str(stream_example), str(path), "--config", str(config), "--out", str(out)],
        check=True,
        capture_output=True,
    )
    rust = np.loadtxt(out, delimiter=",", ndmin=2)
    log = delaynav.read_log(path)
    nav, python, _ = stream_in_python(log, CONFIG)
    assert python.shape == rust.shape == (len(log["imu"]["t_us"]), 35)
    # Estimates exist (the comparison is not of NaN to NaN) ...
    assert np.isfinite(rust[:, 1]).sum() > 0.5 * len(rust)
    # ... and every number is the same double.
    assert np.array_equal(python, rust, equal_nan=True)
    health = nav.health()
    assert health["alignment"] != "Waiting" and "protection_levels" in health
    assert set(nav.integrity()["levels"]) >= {"horizontal_m", "delay_s"}


def stream_with_arrays(log, config):
    """The same stream, each run of IMU samples between two other records
    pushed in one `push_imu_array` call."""
    nav = delaynav.Navigator(config)
    imu, gps, mag = log["imu"], log["gps"], log["mag"]
    order = log["order"]
    blocks, (i_imu, i_gps, i_mag), k = [], (0, 0, 0), 0
    while k < len(order):
        if order[k] == 0:
            end = k
            while end < len(order) and order[end] == 0:
                end += 1
            j = i_imu + (end - k)
            blocks.append(nav.push_imu_array(
                imu["t_us"][i_imu:j], imu["gyro_rad_s"][i_imu:j], imu["accel_m_s2"][i_imu:j], estimates=True, errors="skip"
            ))
            i_imu, k = j, end
            continue
        try:
            if order[k] == 1:
                i_gps += 1
                acc = [None if np.isnan(a) else float(a) for a in gps["accuracy"][i_gps - 1]]
                lat, lon, alt = gps["geodetic"][i_gps - 1]
                nav.push_gps(int(gps["t_us"][i_gps - 1]), lat, lon, alt, gps["velocity_ned_m_s"][i_gps - 1], *acc)
            else:
                i_mag += 1
                nav.push_mag(int(mag["t_us"][i_mag - 1]), mag["field_body"][i_mag - 1])
        except delaynav.SampleError:
            pass
        k += 1
    return nav, np.vstack(blocks)


def test_push_imu_array_matches_push_imu():
    log = delaynav.read_log(log_path("log171.bin"))
    one, rows, refused = stream_in_python(log, CONFIG, count_imu_only=True)
    refused_imu = refused
    arrays, est = stream_with_arrays(log, CONFIG)
    assert est.shape == rows.shape == (len(log["imu"]["t_us"]), len(delaynav.ESTIMATE_COLUMNS))
    assert np.isfinite(est[:, 1]).sum() > 0.5 * len(est)
    # Before the first estimate the array variant's time is NaN too.
    rows[np.isnan(rows[:, 1]), 0] = np.nan
    assert np.array_equal(est, rows, equal_nan=True)
    assert arrays.health() == one.health()
    assert arrays.skipped_samples == refused_imu
    # Without estimates: None, other integer and float dtypes accepted.
    imu = log["imu"]
    nav = delaynav.Navigator(CONFIG)
    t, g, a = imu["t_us"][:100].astype(np.int64), imu["gyro_rad_s"][:100].astype(np.float32), imu["accel_m_s2"][:100]
    assert nav.push_imu_array(t, g, a) is None
    assert nav.health()["refusals"] == delaynav.Navigator(CONFIG).health()["refusals"]


def test_config_errors_name_the_key_the_value_and_the_bound():
    with pytest.raises(delaynav.ConfigError) as err:
        delaynav.Navigator({"imu_rate_hz": float("nan")})
    assert "imu_rate_hz" in str(err.value) and "NaN" in str(err.value)
    with pytest.raises(delaynav.ConfigError) as err:
        delaynav.Navigator({"imu_rate_hz": -5.0})
    assert "imu_rate_hz" in str(err.value) and "-5" in str(err.value)
    with pytest.raises(delaynav.ConfigError, match="nope"):
        delaynav.Navigator({"nope": 1})
    with pytest.raises(delaynav.ConfigError, match="ekf.mag_gate"):
        delaynav.Navigator({"ekf": {"mag_gate": None}})
    with pytest.raises(delaynav.ConfigError, match="not a str"):
        delaynav.Navigator({1: 2.0})
    # A good one reads back.
    nav = delaynav.Navigator({"ekf": {"mag_gate": 16.0}})
    assert nav.config["ekf"]["mag_gate"] == 16.0
    assert "mag_gate = 16.0" in nav.config_toml()


def test_bad_samples_raise_and_never_crash():
    nav = delaynav.Navigator(CONFIG)
    with pytest.raises(ValueError, match="3 values"):
        nav.push_imu(0, [0.0, 0.0], [0.0, 0.0, -9.8])
    with pytest.raises((TypeError, ValueError)):
        nav.push_imu(0, ["a", 0.0, 0.0], [0.0, 0.0, -9.8])
    with pytest.raises((OverflowError, TypeError, ValueError)):
        nav.push_imu(-1, [0.0] * 3, [0.0, 0.0, -9.8])
    n = 10
    t = np.arange(n, dtype=np.uint64) * 20_000
    g, a = np.zeros((n, 3)), np.tile([0.0, 0.0, -9.8], (n, 1))
    with pytest.raises(ValueError, match=r"shape \(10, 3\)"):
        nav.push_imu_array(t, g[:, :2], a)
    with pytest.raises(ValueError, match=r"shape \(10, 3\)"):
        nav.push_imu_array(t, g[:5], a)
    with pytest.raises(ValueError, match="one-dimensional"):
        nav.push_imu_array(t.reshape(2, 5), g, a)
    with pytest.raises(ValueError, match="whole microseconds"):
        nav.push_imu_array(t + 0.5, g, a)
    with pytest.raises(ValueError, match="negative"):
        nav.push_imu_array(t.astype(np.int64) - 100_000, g, a)
    # NaN samples: refused by the library (an error or a counted refusal), never a NaN estimate.
    bad = g.copy()
    bad[3] = np.nan
    try:
        nav.push_imu_array(t, bad, a)
    except delaynav.SampleError as err:
        assert "sample 3" in str(err)
    with pytest.raises(ValueError, match="errors must be"):
        nav.push_imu_array(t, g, a, errors="ignore")
    e = nav.estimate()
    if e is not None:
        assert np.all(np.isfinite(e["attitude"]))
    # Time going backwards: an error or a counted refusal, the navigator still answers.
    try:
        nav.push_imu(0, [0.0] * 3, [0.0, 0.0, -9.8])
    except delaynav.SampleError:
        pass
    assert isinstance(nav.health(), dict)


def test_read_log_missing_file_raises():
    with pytest.raises(delaynav.LogError, match="cannot open"):
        delaynav.read_log("/nonexistent/x.bin")
