"""The `synthetic:` frame source: URI parameters, frames, GT, options, errors."""
from __future__ import annotations

import math

import numpy as np
import pytest

from nicer_stream.errors import SourceError
from sources import open_source
from sources.base import SourceOptions
from tests.sources.synthetic.scene_geometry import bounds
from sources.synthetic import FPS, make_scene


def test_defaults_room_120_frames_320x240_70deg():
    src = open_source("synthetic:")
    assert len(src) == 120 and src.has_gt_pose
    frame = next(iter(src))
    intr = frame.intrinsics
    assert frame.rgb.shape == (240, 320, 3) and (intr.width, intr.height) == (320, 240)
    assert (intr.cx, intr.cy) == (159.5, 119.5) and intr.fx == intr.fy
    assert math.degrees(2 * math.atan(intr.width / 2 / intr.fx)) == pytest.approx(70.0)
    np.testing.assert_allclose(frame.gt_pose, make_scene("room", 0).trajectory(120)[0])


def test_query_params_give_matching_frames_and_ground_truth():
    src = open_source("synthetic:tabletop?frames=4&seed=3&width=64&height=48")
    frames = list(src)
    scene = make_scene("tabletop", 3)
    poses = scene.trajectory(4)
    assert [f.index for f in frames] == [0, 1, 2, 3] and len(src) == 4
    for f in frames:
        assert f.rgb.shape == (48, 64, 3) and f.rgb.dtype == np.float32
        assert f.gt_depth.shape == (48, 64) and f.gt_depth.dtype == np.float32 and (f.gt_depth > 0).all()
        assert f.gt_pose.dtype == np.float64 and f.timestamp == pytest.approx(f.index / FPS)
        np.testing.assert_array_equal(f.gt_pose, poses[f.index])
        view = scene.render(poses[f.index], f.intrinsics)
        np.testing.assert_array_equal(f.rgb, view.rgb)
        np.testing.assert_array_equal(f.gt_depth, view.depth)
    # Consecutive frames differ (the camera moves) and seeds change the scene.
    assert np.abs(frames[0].rgb - frames[1].rgb).mean() > 0.01
    other = next(iter(open_source("synthetic:tabletop?frames=4&seed=4&width=64&height=48")))
    assert np.abs(other.rgb - frames[0].rgb).mean() > 0.01


def test_source_options_select_and_resize():
    opts = SourceOptions(start=1, stride=3, max_frames=2, max_side=32)
    src = open_source("synthetic:room?frames=10&width=64&height=48", opts)
    frames = list(src)
    assert [f.index for f in frames] == [1, 4] and len(src) == 2
    assert frames[0].rgb.shape == (24, 32, 3) and frames[0].gt_depth.shape == (24, 32)
    assert frames[0].intrinsics.fx == pytest.approx(0.5 * open_source("synthetic:room?width=64&height=48").intrinsics.fx)


def test_intrinsics_override_is_used_for_rendering():
    src = open_source("synthetic:room?frames=2&width=40&height=30", SourceOptions(intrinsics=(20.0, 20.0, 19.5, 14.5)))
    frame = next(iter(src))
    assert (frame.intrinsics.fx, frame.intrinsics.cx) == (20.0, 19.5)
    wide = open_source("synthetic:room?frames=2&width=40&height=30")
    assert np.abs(frame.rgb - next(iter(wide)).rgb).mean() > 0.01


@pytest.mark.parametrize(
    "uri",
    [
        "synthetic:room?frames=abc",
        "synthetic:room?frames=0",
        "synthetic:room?width=-5",
        "synthetic:room?height=2.5",
        "synthetic:room?seed=",
        "synthetic:room?fps=10",
        "synthetic:kitchen",
    ],
)
def test_bad_uri_gives_one_line_source_error(uri):
    with pytest.raises(SourceError) as e:
        open_source(uri)
    msg = str(e.value)
    assert msg and "\n" not in msg and "synthetic" in msg


def test_source_exposes_the_gt_mesh_for_evaluation():
    src = open_source("synthetic:room?frames=4")
    mesh = src.gt_mesh()
    lo, hi = bounds(src.scene)
    assert len(mesh.faces) > 100
    assert (mesh.vertices >= lo - 1e-6).all() and (mesh.vertices <= hi + 1e-6).all()
