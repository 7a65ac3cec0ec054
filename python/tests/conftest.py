"""Shared fixtures: where the FCLib problems are, and whether peers are required."""

import os
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
FCLIB = ROOT.parent / "shared" / "data" / "fclib"
IN_CI = os.environ.get("CI") == "true"


def fclib_files():
    """Every shared FCLib problem, global then local."""
    return sorted(FCLIB.glob("global/*.hdf5")) + sorted(FCLIB.glob("local/*.hdf5"))


def require(condition: bool, reason: str) -> None:
    """Skips outside CI when a test's peer or data is missing; fails under CI=true."""
    if condition:
        return
    if IN_CI:
        pytest.fail(f"{reason} (required under CI=true)")
    pytest.skip(reason)
