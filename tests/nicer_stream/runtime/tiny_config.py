"""A tiny configuration (as a TOML file) so end-to-end runs take seconds."""
from pathlib import Path

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
first_iters = 5
rays = 128
eikonal_points = 16
batch_iters = 6
every = 2
keyframe_every = 2
[tracking]
iters = 3
rays = 64
[mesh]
resolution = 24
"""


def write_tiny_config(tmp_path: Path) -> Path:
    path = tmp_path / "tiny.toml"
    path.write_text(TINY_TOML)
    return path
