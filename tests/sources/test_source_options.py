"""SourceOptions selection/resize arithmetic (incl. --drop), URI parsing and the scheme registry."""
from __future__ import annotations

import re

import cv2
import numpy as np
import pytest
from typer.testing import CliRunner

from nicer_stream.cli.common import parse_drop
from nicer_stream.cli.main import app
from nicer_stream.errors import SourceError, UserError
from sources import SCHEMES, open_source, parse_uri
from nicer_stream.types import Frame, Intrinsics
from sources.base import SourceOptions, resize_frame
from sources.synthetic import make_scene


@pytest.mark.parametrize(
    "start,stride,max_frames,n,drop",
    [(0, 1, None, 7, None), (2, 3, None, 20, None), (5, 2, 3, 20, None), (9, 1, 4, 5, None),
     (2, 3, 4, 30, (4, 12)), (0, 1, None, 9, (0, 3))],
)
def test_selected_agrees_with_keeps(start, stride, max_frames, n, drop):
    opts = SourceOptions(start=start, stride=stride, max_frames=max_frames, drop=drop)
    sel = opts.selected(n)
    kept = [i for i in range(n) if opts.keeps(i)]
    assert sel == kept[: max_frames or n]
    assert all(0 <= i < n for i in sel) and sel == sorted(set(sel))


def test_drop_removes_raw_frames_before_max_frames_counts():
    # stride keeps 1, 3, 5, 7, 9, 11, ...; the drop removes raw 4..8; then max_frames takes 4.
    opts = SourceOptions(start=1, stride=2, drop=(4, 9), max_frames=4)
    assert opts.selected(20) == [1, 3, 9, 11]
    assert not opts.keeps(5) and not opts.keeps(7) and opts.keeps(9)
    assert SourceOptions(drop=(2, 4)).selected(6) == [0, 1, 4, 5]
    assert SourceOptions(drop=(0, 100)).selected(6) == []
    assert SourceOptions(drop=(10, 20)).selected(6) == list(range(6))  # beyond the input: nothing to drop


@pytest.mark.parametrize("drop", [(5, 5), (6, 2), (-1, 3)])
def test_bad_drop_raises_one_line_saying_what_to_give(drop):
    with pytest.raises(SourceError) as e:
        SourceOptions(drop=drop)
    msg = str(e.value)
    assert "\n" not in msg and f"--drop {drop[0]}:{drop[1]}" in msg and "A:B" in msg and "0 <= A < B" in msg


def test_parse_drop_flag():
    assert parse_drop("3:7") == (3, 7) and parse_drop(None) is None and parse_drop("") is None
    for bad in ("3", "3-7", "a:b", "3:7:9"):
        with pytest.raises(UserError, match="--drop must be 'A:B'"):
            parse_drop(bad)


def test_synthetic_source_honours_drop_and_keeps_raw_indices():
    opts = SourceOptions(stride=2, drop=(3, 8), max_frames=3, max_side=16)
    src = open_source("synthetic:room?frames=14&width=32&height=24", opts)
    frames = list(src)
    assert [f.index for f in frames] == [0, 2, 8] and len(src) == 3
    poses = make_scene("room", 0).trajectory(14)
    for f in frames:
        np.testing.assert_array_equal(f.gt_pose, poses[f.index])  # GT still matches the raw frame


@pytest.mark.parametrize("command", ["run", "map", "eval", "priors"])
def test_every_command_with_stride_accepts_drop(command):
    res = CliRunner().invoke(app, [command, "--help"], terminal_width=200)
    assert res.exit_code == 0 and "--stride" in res.output and "--drop" in res.output


def test_eval_rejects_a_bad_drop_in_one_line(tmp_path):
    res = CliRunner().invoke(app, ["eval", str(tmp_path), "--source", "synthetic:room?frames=4", "--drop", "5:2"])
    assert res.exit_code == 2 and "--drop 5:2" in res.output and len(res.output.strip().splitlines()) == 1


def test_target_size():
    assert SourceOptions(max_side=320).target_size(1200, 680) == (320, 181)
    assert SourceOptions(max_side=320).target_size(480, 640) == (240, 320)
    assert SourceOptions(max_side=2000).target_size(1200, 680) == (1200, 680)  # never upsamples
    assert SourceOptions(scale=0.5).target_size(641, 480) == (320, 240)
    assert SourceOptions().target_size(17, 9) == (17, 9)


def test_the_detail_image_is_the_larger_grey_copy_with_its_own_intrinsics():
    """max_side 50 with detail_side 120 on a 200 x 100 frame: the map's image 50 x 25, the grey copy
    120 x 60 (the area-resized RGB's luminance, uint8) with the camera's intrinsics at that size;
    none when it would be no larger than the map's image; the original when the side exceeds it."""
    rng = np.random.default_rng(0)
    intr = Intrinsics(180.0, 170.0, 99.5, 49.5, 200, 100)
    frame = Frame(0, 0.0, rng.random((100, 200, 3), dtype=np.float32), intr)
    out = resize_frame(frame, SourceOptions(max_side=50, detail_side=120))
    assert out.rgb.shape == (25, 50, 3) and out.intrinsics == intr.resized(50, 25)
    d = out.detail
    assert d.grey.shape == (60, 120) and d.grey.dtype == np.uint8 and d.intrinsics == intr.resized(120, 60)
    ref = cv2.cvtColor(cv2.resize(frame.rgb, (120, 60), interpolation=cv2.INTER_AREA), cv2.COLOR_RGB2GRAY) * 255
    assert np.abs(d.grey.astype(np.float32) - ref).max() <= 1.0
    assert resize_frame(frame, SourceOptions(max_side=50, detail_side=40)).detail is None
    assert resize_frame(frame, SourceOptions(detail_side=400)).detail is None  # no resize: rgb is the largest
    full = resize_frame(frame, SourceOptions(max_side=50, detail_side=400)).detail
    assert full.grey.shape == (100, 200) and full.intrinsics == intr
    assert resize_frame(frame, SourceOptions(max_side=50)).detail is None


@pytest.mark.parametrize("kwargs", [dict(stride=0), dict(start=-1), dict(max_frames=0), dict(max_side=10, scale=0.5)])
def test_invalid_options_raise_one_line(kwargs):
    with pytest.raises(SourceError) as e:
        SourceOptions(**kwargs)
    assert "\n" not in str(e.value) and "--" in str(e.value)


def test_a_detail_side_below_one_pixel_is_refused_in_one_line():
    with pytest.raises(SourceError, match="detail_side must be a positive number of pixels, got 0"):
        SourceOptions(detail_side=0)


def test_parse_uri():
    assert parse_uri("replica:/data/room0") == ("replica", "/data/room0", {})
    assert parse_uri("folder:rel/dir?fps=15&x=") == ("folder", "rel/dir", {"fps": "15", "x": ""})
    assert parse_uri("tum:C:/x") == ("tum", "C:/x", {})  # only the first ':' splits
    with pytest.raises(SourceError, match="no scheme"):
        parse_uri("/just/a/path")


def test_unknown_scheme(tmp_path):
    with pytest.raises(SourceError) as e:
        open_source(f"kitti:{tmp_path}")
    msg = str(e.value)
    assert "kitti" in msg and all(s in msg for s in SCHEMES) and "\n" not in msg


@pytest.mark.parametrize("scheme", ["replica", "tum", "7scenes", "folder"])
def test_missing_path_every_scheme(scheme, tmp_path):
    missing = tmp_path / "does" / "not" / "exist"
    with pytest.raises(SourceError, match=re.escape(f"source path {missing} does not exist")):
        open_source(f"{scheme}:{missing}")


def test_uri_recorded_on_source(replica_dir):
    uri = f"replica:{replica_dir}?fps=30"
    assert open_source(uri).uri == uri
