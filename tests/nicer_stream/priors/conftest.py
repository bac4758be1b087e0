"""Fixtures for the prior tests: a few real Replica frames, small."""
from __future__ import annotations

from pathlib import Path

import pytest

from nicer_stream.types import Frame


@pytest.fixture(scope="session")
def replica_small(replica_dir: Path) -> list[Frame]:
    """First 3 Replica room0 frames resized to 160 px wide, with GT depth and poses."""
    from sources import open_source
    from sources.base import SourceOptions

    return list(open_source(f"replica:{replica_dir}", SourceOptions(max_frames=3, max_side=160)))
