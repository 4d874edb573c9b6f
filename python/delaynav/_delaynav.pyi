"""Type stubs of the extension module (Rust, pyo3). Use the wrappers of
``delaynav`` (``delaynav/__init__.py``); these are their raw calls."""

from typing import Any

import numpy as np
import numpy.typing as npt

ESTIMATE_COLUMNS: int

class DelaynavError(Exception):
    """Every error of the delaynav library (its message is the library's)."""

class ConfigError(DelaynavError):
    """An invalid configuration: names the key, the value and the bound."""

class LogError(DelaynavError):
    """A log that cannot be found, read or replayed."""

class SampleError(DelaynavError):
    """A sample the navigator refused with an error."""

def replay(
    path: str,
    config: dict[str, Any] | None = None,
    estimators: list[str] = ["proposed"],
    traces: bool = True,
    reference: bool = False,
) -> dict[str, Any]: ...
def batch(
    paths: list[str],
    workers: int | None = None,
    estimators: list[str] = ["proposed"],
) -> list[tuple[dict[str, Any] | None, str | None]]: ...
def read_log(path: str, imu_instance: int = 0) -> dict[str, Any]: ...

class Navigator:
    def __init__(self, config: dict[str, Any] | None = None) -> None: ...
    def config(self) -> dict[str, Any]: ...
    def config_toml(self) -> str: ...
    def push_imu(self, t_us: int, gyro: list[float], accel: list[float]) -> None: ...
    def push_gps(
        self,
        t_us: int,
        position: list[float],
        velocity_ned: list[float],
        geodetic: bool,
        horizontal_accuracy_m: float | None = None,
        vertical_accuracy_m: float | None = None,
        speed_accuracy_m_s: float | None = None,
    ) -> str: ...
    def push_mag(self, t_us: int, field_body: list[float]) -> str: ...
    def push_imu_array(
        self,
        t_us: npt.NDArray[np.uint64],
        gyro: npt.NDArray[np.float64],
        accel: npt.NDArray[np.float64],
        estimates: bool = False,
        skip_errors: bool = False,
    ) -> tuple[npt.NDArray[np.float64] | None, int]: ...
    def estimate(self) -> dict[str, Any] | None: ...
    def health(self) -> dict[str, Any]: ...
    def integrity(self) -> dict[str, Any]: ...
