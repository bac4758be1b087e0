"""`nicer-stream map` (known poses): the output contract, and the same monocular-prior fusion
as a SLAM run with `fast`."""
import json
import re

import numpy as np
import pytest

from nicer_stream.errors import UserError
from nicer_stream.io import output_dir as od
from nicer_stream.io.trajectory import read_tum
from nicer_stream.runtime.map_known_poses import MapRequest, run_map
from sources import open_source
from sources.base import SourceOptions


@pytest.mark.parametrize("priors", ["oracle", "none"])
def test_map_with_known_poses_fuses_a_monocular_prior_like_the_slam(tmp_path, tiny_config, priors):
    src = "synthetic:room?frames=40"
    opts = SourceOptions(max_frames=8, stride=4, max_side=96)  # parallax enough for a sweep at this size
    out = run_map(MapRequest(source=src, out_dir=tmp_path / "out", poses="gt", priors=priors, config_file=str(tiny_config),
                             iters=4, source_opts=opts))
    _, poses = read_tum(out / od.TRAJECTORY_FILE)
    gt = np.stack([f.gt_pose for f in open_source(src, opts)])
    np.testing.assert_allclose(poses, gt, atol=1e-6)
    notes = json.loads((out / od.SUMMARY_FILE).read_text())["notes"]
    fused = [n for n in notes if "stereo.mono_fusion" in n]
    if priors == "none":
        assert not fused
    else:  # each frame's prior is fitted to its own sweep (or kept, and counted)
        assert len(fused) == 1 and re.search(r": [5-8] of 8 frames", fused[0]), notes
    assert (out / od.SUMMARY_FILE).is_file() and any((out / od.RENDERS_DIR).glob("*.npz"))


def test_map_refuses_stereo_priors_in_one_line(tmp_path):
    with pytest.raises(UserError, match="needs the SLAM's poses"):
        run_map(MapRequest(source="synthetic:room?frames=4", out_dir=tmp_path / "out", poses="gt", priors="stereo"))
