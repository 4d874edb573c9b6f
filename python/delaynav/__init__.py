"""delaynav from Python: the replay of a flight log, the streaming navigator,
and fleets of logs.

The work is done by the Rust library (``delaynav``) through its extension
module ``delaynav._delaynav``; this module gives it a Python shape:

- :func:`replay` replays one log (an ArduPilot ``.bin``, a PX4 ``.ulg`` or a
  folder of CSVs) exactly as ``delaynav replay LOG --json`` does and returns
  a :class:`Replay`: the summary (the command line's JSON, as a dict) and
  every estimate as numpy arrays.
- :class:`Navigator` is the streaming delay-compensated navigator: push IMU,
  GPS and magnetometer samples one by one or IMU samples as arrays
  (:meth:`Navigator.push_imu_array`, the loop in Rust).
- :func:`batch` replays many logs in parallel threads (the GIL released);
  :func:`summary_row` flattens a summary into one table row (pandas, Dask).
- :func:`read_log` reads a log's records with the library's reader.

Errors of the library are raised as :class:`DelaynavError` subclasses with
the library's messages: :class:`ConfigError` (names the key, the value and
the bound), :class:`LogError`, :class:`SampleError`.
"""

from __future__ import annotations

import os
from typing import Any, Iterable, Mapping, Sequence

import numpy as np

from . import _delaynav
from ._delaynav import ConfigError, DelaynavError, LogError, SampleError

__all__ = [
    "ConfigError",
    "DelaynavError",
    "LogError",
    "Navigator",
    "Replay",
    "SampleError",
    "batch",
    "read_log",
    "replay",
    "summary_row",
]

#: Columns of :meth:`Navigator.push_imu_array`'s estimates, in order.
ESTIMATE_COLUMNS: tuple[str, ...] = (
    ("t_us", "qw", "qx", "qy", "qz", "north_m", "east_m", "down_m")
    + ("vn_m_s", "ve_m_s", "vd_m_s")
    + ("accel_bias_x", "accel_bias_y", "accel_bias_z")
    + ("gyro_bias_x", "gyro_bias_y", "gyro_bias_z")
    + tuple(f"var_{i}" for i in range(16))
    + ("delay_s", "delay_std_s")
)
assert len(ESTIMATE_COLUMNS) == _delaynav.ESTIMATE_COLUMNS


def _names(estimators: str | Iterable[str]) -> list[str]:
    if isinstance(estimators, str):
        return [estimators]
    return [str(e) for e in estimators]


class Replay:
    """One log replayed (see :func:`replay`).

    Attributes:
        path: the log.
        summary: the replay's JSON summary as a dict, the same document as
            ``delaynav replay LOG --json`` writes (``summary["estimators"]``:
            one entry per estimator, its figures and its health).
        derived: the defaults derived from the log (``summary["derived"]``).
        config: the navigator's configuration the replay used, as a dict.
        notes: what the setup found and warned about, in order.
        table: the console table and health summary, as the command line
            prints it.
        traces: per estimator name, every estimate of the scored pass as
            numpy arrays (see :meth:`trace`).
        reference: the log's reference attitude ``[t s, roll, pitch, yaw
            deg]`` in the replayed window (``None`` unless asked for or when
            the log has none).
    """

    def __init__(self, path: str, raw: dict[str, Any]):
        self.path = path
        self.summary: dict[str, Any] = raw["summary"]
        self.derived: dict[str, Any] = self.summary["derived"]
        self.config: dict[str, Any] = raw["config"]
        self.notes: list[str] = raw["notes"]
        self.log_line: str = raw["log_line"]
        self.table: str = raw["table"]
        self.traces: dict[str, dict[str, np.ndarray]] = raw["traces"]
        self.reference: np.ndarray | None = raw.get("reference")

    @property
    def estimators(self) -> list[str]:
        """The estimators replayed, in report order."""
        return [e["estimator"] for e in self.summary["estimators"]]

    def estimator(self, name: str | None = None) -> dict[str, Any]:
        """The summary entry of ``name`` (default: the first estimator)."""
        name = name or self.estimators[0]
        for entry in self.summary["estimators"]:
            if entry["estimator"] == name:
                return entry
        raise KeyError(f"estimator {name!r} was not replayed; replayed: {self.estimators}")

    def trace(self, name: str | None = None) -> dict[str, np.ndarray]:
        """Every estimate of ``name`` (default: the first estimator), as arrays:

        ``t_us`` (n,) IMU clock, microseconds; ``time_s`` (n,) seconds;
        ``attitude`` (n, 4) body-to-NED quaternion w, x, y, z;
        ``euler_deg`` (n, 3) roll, pitch, yaw; ``aligned_euler_deg`` (n, 3)
        the same aligned like the log's reference (trim and declination);
        ``position_ned_m``, ``velocity_ned_m_s`` (n, 3) NED from the first
        fix; ``accel_bias_m_s2``, ``gyro_bias_rad_s`` (n, 3) body FRD;
        ``covariance_diagonal`` (n, 16); ``delay_s``, ``delay_std_s`` (n,)
        the GPS delay estimate and its standard deviation (NaN where the
        estimator has none); ``protection_levels`` (n, 6) and ``valid`` (n, 6)
        the estimator's protection levels and validity flags at each estimate,
        columns ``level_names`` (tilt_deg, heading_deg, horizontal_m,
        vertical_m, velocity_m_s, delay_s; an infinite level vouches for
        nothing).
        """
        name = name or self.estimators[0]
        if name not in self.traces:
            raise KeyError(f"no trace of {name!r}; kept: {sorted(self.traces)}")
        t = dict(self.traces[name])
        t["time_s"] = t["t_us"] * 1e-6
        return t

    # The arrays of the first estimator, as attributes.
    @property
    def time_s(self) -> np.ndarray:
        """Time of each estimate, seconds on the log's clock."""
        return self.trace()["time_s"]

    @property
    def attitude(self) -> np.ndarray:
        """(n, 4) body-to-NED quaternion w, x, y, z."""
        return self.trace()["attitude"]

    @property
    def euler_deg(self) -> np.ndarray:
        """(n, 3) roll, pitch, yaw, degrees."""
        return self.trace()["euler_deg"]

    @property
    def position_ned_m(self) -> np.ndarray:
        """(n, 3) position NED, metres from the local origin."""
        return self.trace()["position_ned_m"]

    @property
    def velocity_ned_m_s(self) -> np.ndarray:
        """(n, 3) velocity NED, m/s."""
        return self.trace()["velocity_ned_m_s"]

    @property
    def delay_s(self) -> np.ndarray:
        """(n,) GPS delay estimate, seconds (NaN where none)."""
        return self.trace()["delay_s"]

    @property
    def delay_std_s(self) -> np.ndarray:
        """(n,) standard deviation of the delay estimate, seconds."""
        return self.trace()["delay_std_s"]

    @property
    def protection_levels(self) -> np.ndarray:
        """(n, 6) protection levels at each estimate: tilt and heading (deg),
        horizontal and vertical position (m), velocity (m/s), delay (s)."""
        return self.trace()["protection_levels"]

    @property
    def valid(self) -> np.ndarray:
        """(n, 6) validity flags of the same six quantities (level within its
        alert limit)."""
        return self.trace()["valid"]

    @property
    def health(self) -> dict[str, Any]:
        """The first estimator's health at the end of the replay (refusals,
        gates, resets, alignment, delay status), as in the summary."""
        return self.estimator()["health"]

    def to_pandas(self, name: str | None = None):
        """The trace of ``name`` as a pandas DataFrame indexed by ``time_s``
        (needs pandas)."""
        import pandas as pd

        t = self.trace(name)
        columns: dict[str, np.ndarray] = {"t_us": t["t_us"]}
        triples = {
            "euler_deg": ("roll_deg", "pitch_deg", "yaw_deg"),
            "position_ned_m": ("north_m", "east_m", "down_m"),
            "velocity_ned_m_s": ("vn_m_s", "ve_m_s", "vd_m_s"),
            "accel_bias_m_s2": ("accel_bias_x", "accel_bias_y", "accel_bias_z"),
            "gyro_bias_rad_s": ("gyro_bias_x", "gyro_bias_y", "gyro_bias_z"),
        }
        for key, names in triples.items():
            for i, col in enumerate(names):
                columns[col] = t[key][:, i]
        for i, col in enumerate(("qw", "qx", "qy", "qz")):
            columns[col] = t["attitude"][:, i]
        columns["delay_s"] = t["delay_s"]
        columns["delay_std_s"] = t["delay_std_s"]
        for i, level in enumerate(t["level_names"]):
            quantity = level.rsplit("_", 2 if level.endswith("_m_s") else 1)[0]
            columns[f"pl_{level}"] = t["protection_levels"][:, i]
            columns[f"{quantity}_valid"] = t["valid"][:, i]
        return pd.DataFrame(columns, index=pd.Index(t["time_s"], name="time_s"))

    def row(self) -> dict[str, Any]:
        """This replay as one table row (:func:`summary_row`)."""
        return summary_row(self.path, self.summary)

    def __repr__(self) -> str:
        return f"Replay({self.path!r}, estimators={self.estimators})"


def replay(
    path: str | os.PathLike[str],
    config: Mapping[str, Any] | None = None,
    estimators: str | Iterable[str] = ("proposed",),
    *,
    traces: bool = True,
    reference: bool = False,
) -> Replay:
    """Replays the log at ``path`` through ``estimators``, as
    ``delaynav replay LOG --json`` does.

    Args:
        path: an ArduPilot ``.bin``, a PX4 ``.ulg``, or a folder of CSVs (the
            crate's, ArduPilot's or PX4 ``ulog2csv``'s).
        config: the navigator's configuration, possibly partial, merged over
            the one derived from the log, like the command line's
            ``--config FILE`` (the same keys as its TOML: ``{"ekf":
            {"mag_gate": 16.0}}``). An unknown key, a wrong type or an
            invalid value raises :class:`ConfigError` naming the key, the
            value and the bound.
        estimators: names among ``"proposed"``, ``"aekf17"``, ``"ekf16"``,
            or ``"all"``.
        traces: keep every estimate as arrays (``False``: the summary only).
        reference: also read the log's reference attitude.

    Raises:
        LogError: the log is missing, unreadable or in no known format.
        ConfigError: ``config`` is invalid.
        ValueError: an unknown estimator name.
    """
    raw = _delaynav.replay(
        os.fspath(path),
        dict(config) if config is not None else None,
        _names(estimators),
        traces,
        reference,
    )
    return Replay(os.fspath(path), raw)


def batch(
    paths: Iterable[str | os.PathLike[str]],
    workers: int | None = None,
    estimators: str | Iterable[str] = ("proposed",),
) -> list[dict[str, Any]]:
    """Replays every log of ``paths`` in this process, ``workers`` logs at a
    time (threads in Rust, the GIL released; ``None``: every core). A log that
    fails is a row with its ``error``, never a stop.

    Returns one row per path, in order (:func:`summary_row`); ``pandas.
    DataFrame(batch(paths))`` is the fleet's table.
    """
    paths = [os.fspath(p) for p in paths]
    if workers is not None and workers < 1:
        raise ValueError(f"workers must be at least 1, got {workers}")
    rows = []
    outcomes = _delaynav.batch(paths, workers, _names(estimators))
    for path, (summary, error) in zip(paths, outcomes):
        rows.append(summary_row(path, summary) if error is None else {"file": path, "error": error})
    return rows


def summary_row(path: str, summary: Mapping[str, Any]) -> dict[str, Any]:
    """A replay's summary as one flat row: the log, its window and counts,
    and per estimator (``NAME.`` prefix) its delay and its attitude and
    velocity RMS against the log's reference."""
    row: dict[str, Any] = {
        "file": os.fspath(path),
        "error": None,
        "format": summary["format"],
        "imu": summary["counts"]["imu"],
        "gps": summary["counts"]["gps"],
        "mag": summary["counts"]["mag"],
        "scored_from_s": summary["scored_from_s"],
        "to_s": summary["to_s"],
        "imu_rate_hz": summary["imu_rate_hz"],
    }
    for e in summary["estimators"]:
        name = e["estimator"]
        for key in (
            "final_delay_s",
            "roll_rms_deg",
            "pitch_rms_deg",
            "yaw_rms_deg",
            "velocity_rms_m_s",
            "samples_refused",
        ):
            row[f"{name}.{key}"] = e.get(key)
        row[f"{name}.alignment"] = e["health"].get("alignment")
    return row


def read_log(path: str | os.PathLike[str], imu_instance: int = 0) -> dict[str, Any]:
    """Every record of the log at ``path`` as read by the library's reader
    (the replay's): ``imu`` (``t_us``, ``gyro_rad_s``, ``accel_m_s2``),
    ``gps`` (``t_us`` receive time, ``geodetic`` lat deg, lon deg, alt m or
    ``position_ned_m`` (the other NaN), ``velocity_ned_m_s``, ``accuracy``
    horizontal m, vertical m, speed m/s, NaN when not reported), ``mag``
    (``t_us``, ``field_body``) and ``order``: the records in the reader's
    order (0 IMU, 1 GPS, 2 magnetometer)."""
    return _delaynav.read_log(os.fspath(path), imu_instance)


def _vector3(value: Any, what: str) -> list[float]:
    v = np.asarray(value, dtype=np.float64)
    if v.shape != (3,):
        raise ValueError(f"{what} must have 3 values, got shape {v.shape}")
    return [float(x) for x in v]


def _optional(value: float | None) -> float | None:
    return None if value is None else float(value)


class Navigator:
    """The streaming delay-compensated navigator (double precision).

    Args:
        config: the configuration, possibly partial, merged over the
            library's defaults (the keys of a replay's TOML configuration
            file, e.g. ``{"imu_rate_hz": 50.0, "ekf": {"mag_declination_rad":
            0.2}}``). Invalid: :class:`ConfigError` naming the key, the value
            and the bound.

    Times are integer microseconds on the IMU clock; body axes FRD, world
    NED; gyro rad/s, specific force m/s^2, magnetic field in any unit.
    """

    def __init__(self, config: Mapping[str, Any] | None = None):
        self._nav = _delaynav.Navigator(dict(config) if config is not None else None)
        #: Samples :meth:`push_imu_array` skipped (``errors="skip"``) because
        #: the library refused them with an error.
        self.skipped_samples = 0

    @property
    def config(self) -> dict[str, Any]:
        """The resolved configuration, as a dict."""
        return self._nav.config()

    def config_toml(self) -> str:
        """The resolved configuration as TOML (a replay's ``--config`` file)."""
        return self._nav.config_toml()

    def push_imu(self, t_us: int, gyro_rad_s: Sequence[float], accel_m_s2: Sequence[float]) -> None:
        """Feeds one IMU sample (time must increase). Raises
        :class:`SampleError` when the library refuses it with an error."""
        self._nav.push_imu(int(t_us), _vector3(gyro_rad_s, "gyro_rad_s"), _vector3(accel_m_s2, "accel_m_s2"))

    def push_gps(
        self,
        t_us: int,
        lat_deg: float,
        lon_deg: float,
        alt_m: float,
        velocity_ned_m_s: Sequence[float],
        horizontal_accuracy_m: float | None = None,
        vertical_accuracy_m: float | None = None,
        speed_accuracy_m_s: float | None = None,
    ) -> str:
        """Feeds one GPS fix stamped with its receive time. Returns what
        happened to it: ``"waiting"``, ``"initialized"``, ``"fused"`` or
        ``"queued"``."""
        position = [float(lat_deg), float(lon_deg), float(alt_m)]
        return self._nav.push_gps(
            int(t_us),
            position,
            _vector3(velocity_ned_m_s, "velocity_ned_m_s"),
            True,
            _optional(horizontal_accuracy_m),
            _optional(vertical_accuracy_m),
            _optional(speed_accuracy_m_s),
        )

    def push_gps_ned(
        self,
        t_us: int,
        position_ned_m: Sequence[float],
        velocity_ned_m_s: Sequence[float],
        horizontal_accuracy_m: float | None = None,
        vertical_accuracy_m: float | None = None,
        speed_accuracy_m_s: float | None = None,
    ) -> str:
        """:meth:`push_gps` with a local NED position, metres."""
        return self._nav.push_gps(
            int(t_us),
            _vector3(position_ned_m, "position_ned_m"),
            _vector3(velocity_ned_m_s, "velocity_ned_m_s"),
            False,
            _optional(horizontal_accuracy_m),
            _optional(vertical_accuracy_m),
            _optional(speed_accuracy_m_s),
        )

    def push_mag(self, t_us: int, field_body: Sequence[float]) -> str:
        """Feeds one magnetometer sample (body frame). Returns ``"stored"``,
        ``"fused"`` or ``"queued"``."""
        return self._nav.push_mag(int(t_us), _vector3(field_body, "field_body"))

    def push_imu_array(
        self,
        t_us: Any,
        gyro_rad_s: Any,
        accel_m_s2: Any,
        *,
        estimates: bool = False,
        errors: str = "raise",
    ):
        """Feeds ``n`` IMU samples, the loop in Rust with the GIL released.

        Args:
            t_us: (n,) integer microseconds, increasing.
            gyro_rad_s, accel_m_s2: (n, 3).
            estimates: also return the estimate after each sample.
            errors: ``"raise"``: a sample refused with an error raises
                :class:`SampleError` (the samples before it were pushed);
                ``"skip"``: it is counted in :attr:`skipped_samples` and the
                loop goes on (what a per-sample loop catching the error does).

        Returns:
            ``None``, or with ``estimates`` an (n, 35) array whose columns
            are :data:`ESTIMATE_COLUMNS` (NaN rows before the first
            estimate).

        Raises:
            ValueError: wrong shapes or a negative time.
            SampleError: a sample refused with an error (its index and time
                in the message; the samples before it were pushed).
        """
        t = np.asarray(t_us)
        if t.ndim != 1:
            raise ValueError(f"t_us must be one-dimensional, got shape {t.shape}")
        if t.dtype.kind == "f":
            if not np.all(np.isfinite(t)) or np.any(t != np.round(t)):
                raise ValueError("t_us must be whole microseconds")
        elif t.dtype.kind not in "iu":
            raise ValueError(f"t_us must be integers, got dtype {t.dtype}")
        if t.size and t.min() < 0:
            raise ValueError("t_us must not be negative")
        t = np.ascontiguousarray(t, dtype=np.uint64)
        g = np.ascontiguousarray(gyro_rad_s, dtype=np.float64)
        a = np.ascontiguousarray(accel_m_s2, dtype=np.float64)
        for name, arr in (("gyro_rad_s", g), ("accel_m_s2", a)):
            if arr.shape != (t.shape[0], 3):
                raise ValueError(f"{name} must have shape ({t.shape[0]}, 3), got {arr.shape}")
        if errors not in ("raise", "skip"):
            raise ValueError(f"errors must be 'raise' or 'skip', got {errors!r}")
        out, skipped = self._nav.push_imu_array(t, g, a, estimates, errors == "skip")
        self.skipped_samples += skipped
        return out

    def estimate(self) -> dict[str, Any] | None:
        """The current solution (``t_us``, ``attitude`` w x y z,
        ``euler_deg``, ``position_ned_m``, ``velocity_ned_m_s``, biases,
        ``covariance_diagonal``, ``delay_s``, ``delay_std_s``), ``None``
        until initialized."""
        return self._nav.estimate()

    def health(self) -> dict[str, Any]:
        """The navigator's health report: alignment, per-quantity validity,
        protection levels, last reset, refusal counters, delay loop, magnetic
        mode, yaw estimator."""
        return self._nav.health()

    def integrity(self) -> dict[str, Any]:
        """What the navigator vouches for: protection levels and, per
        quantity, whether it is valid."""
        return self._nav.integrity()
