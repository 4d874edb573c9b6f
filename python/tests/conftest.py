"""Shared fixtures: the repository, the shared logs, the Rust binaries the
Python package is checked against (built with cargo when absent)."""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
DATA = Path(os.environ.get("DELAYNAV_DATA", REPO.parent / "shared" / "data"))
TARGET = Path(os.environ.get("CARGO_TARGET_DIR", REPO / "target"))

#: The shared logs: ArduPilot's binary log, its CSV export, the two PX4 ULog samples.
LOGS = {
    "log171.bin": DATA / "ardupilot-log171" / "log171.bin",
    "log171-csv": DATA / "ardupilot-log171",
    "sample_log_small.ulg": DATA / "px4-pyulog-sample" / "sample_log_small.ulg",
    "sample_px4_events.ulg": DATA / "px4-pyulog-sample" / "sample_px4_events.ulg",
}


def log_path(name: str) -> Path:
    """The shared log `name`, or a skip saying it is absent (outside CI)."""
    path = LOGS[name]
    if not path.exists():
        if os.environ.get("CI") == "true":
            pytest.fail(f"{path} is missing: the shared logs must be beside the repository in CI")
        pytest.skip(f"{path} is missing (the shared logs live in ../shared/data)")
    return path


def _binary(path: Path, build: list[str]) -> Path:
    if not path.exists():
        subprocess.run(["cargo", "build", "--release", "--quiet", *build], cwd=REPO, check=True)
    return path


@pytest.fixture(scope="session")
def cli() -> Path:
    """The `delaynav` command (cli/), release build."""
    return _binary(TARGET / "release" / "delaynav", ["-p", "delaynav-cli"])


@pytest.fixture(scope="session")
def stream_example() -> Path:
    """The `stream` example: a log through one navigator, every estimate written."""
    return _binary(
        TARGET / "release" / "examples" / "stream",
        ["--features", "replay", "--example", "stream"],
    )
