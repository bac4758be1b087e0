"""The depth prior's shift recovered from the normal prior (first SLAM mapping)."""
from __future__ import annotations

import numpy as np
import pytest

from nicer_stream.mapping.depth_shift import normal_disagreement, shift_from_normals
from nicer_stream.geometry.depth_normals import normals_from_depth
from sources import open_source


@pytest.fixture(scope="module")
def frame():
    return next(iter(open_source("synthetic:room?frames=2")))


@pytest.mark.parametrize("scale,shift", [(1.3, 0.8), (0.6, 0.0), (2.0, 2.5)])
def test_shift_recovered_on_synthetic_room(frame, scale, shift):
    d = frame.gt_depth
    normal = normals_from_depth(d, frame.intrinsics)
    prior = scale * d + shift
    q = shift_from_normals(prior, normal, frame.intrinsics)
    assert abs(q - shift) < 0.03 * float(np.median(prior))


def test_scale_does_not_change_the_normals(frame):
    d, intr = frame.gt_depth, frame.intrinsics
    n = normals_from_depth(d, intr)
    assert normal_disagreement(d, n, intr) == pytest.approx(normal_disagreement(3.0 * d, n, intr), abs=1e-6)
    assert normal_disagreement(d + 1.0, n, intr) > normal_disagreement(d, n, intr) + 0.01


def test_mostly_invalid_prior_gives_zero_shift(frame):
    prior = np.zeros_like(frame.gt_depth)
    prior[:5] = 1.0
    assert shift_from_normals(prior, normals_from_depth(frame.gt_depth, frame.intrinsics), frame.intrinsics) == 0.0
