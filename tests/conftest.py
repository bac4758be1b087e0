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


# A tiny configuration so that end-to-end runs take seconds (overrides the `fast` preset).
TINY_TOML = """
max_side = 48
[model]
coarse_res = 16
fine_levels = 2
fine_res_min = 16
fine_res_max = 24
color_levels = 2
color_res_max = 32
color_log2_table = 12
[render]
n_probe = 16
n_importance = 8
n_uniform = 2
chunk_rays = 4096
[mapping]
iters = 3
final_iters = 4
first_iters = 5
rays = 128
eikonal_points = 16
batch_iters = 6
every = 2
keyframe_every = 2
# A keyframe and a mapping call every 2 frames: the schedule these tests count on (view
# keyframes, `slam/keyframes.py`, are tested on their own).
keyframes = "stride"
[tracking]
iters = 3
rays = 64
# The paper's tracking on every frame: the mechanics these tests check, at 48 px where the
# classical frontend (`fast`'s default, tested in tests/nicer_stream/frontend/) finds few tracks.
frontend = "none"
refine = "all"
[mesh]
resolution = 24
"""


@pytest.fixture
def tiny_config(tmp_path: Path) -> Path:
    """Path of a TOML config file with tiny models, images and iteration counts."""
    path = tmp_path / "tiny.toml"
    path.write_text(TINY_TOML)
    return path


@pytest.fixture(scope="session")
def tiny_toml() -> str:
    """The text of the tiny configuration (for fixtures wider than one test)."""
    return TINY_TOML
