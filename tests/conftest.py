"""Shared fixtures: the real drives in ../shared/data.

Tests that need them use the ``shared_data`` fixture: it skips with a clear
reason when the folder is absent, and fails instead when
``GRADGPS_REQUIRE_SHARED=1`` (CI sets it), so CI can never pass by skipping.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
SHARED_DATA = Path(os.environ.get("GRADGPS_DATA", REPO.parent / "shared" / "data"))


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """Folder holding driveplotr_nds.csv and tuc_urban_gt.csv."""
    present = (SHARED_DATA / "driveplotr_nds.csv").is_file() and (
        SHARED_DATA / "tuc_urban_gt.csv"
    ).is_file()
    if not present:
        msg = f"shared data not found at {SHARED_DATA} (set GRADGPS_DATA or put ../shared/data beside the checkout)"
        if os.environ.get("GRADGPS_REQUIRE_SHARED") == "1":
            pytest.fail(msg + "; GRADGPS_REQUIRE_SHARED=1 forbids skipping")
        pytest.skip(msg)
    return SHARED_DATA
