"""Shared fixtures: the read-only real data at `<repo>/../shared/data` (skipped if absent)."""
from __future__ import annotations

from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
DATA = REPO.parent / "shared" / "data"


@pytest.fixture(scope="session")
def data_dir() -> Path:
    """Root of the shared real data (README.md there); skips the test if missing."""
    if not DATA.is_dir():
        pytest.skip(f"real data not found at {DATA}")
    return DATA


@pytest.fixture(scope="session")
def replica_dir(data_dir: Path) -> Path:
    """Replica room0, first 20 frames, NICE-SLAM layout (1200x680, traj.txt, depth)."""
    p = data_dir / "replica_room0_20f"
    if not p.is_dir():
        pytest.skip(f"{p} missing")
    return p


@pytest.fixture(scope="session")
def tum_dir(data_dir: Path) -> Path:
    """TUM fr3/long_office_household, 4 frames (640x480, rgb.txt, groundtruth.txt, intrinsics.txt)."""
    p = data_dir / "tum_fr3_office_4f"
    if not p.is_dir():
        pytest.skip(f"{p} missing")
    return p
