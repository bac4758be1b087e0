"""SourceOptions selection/resize arithmetic, URI parsing and the scheme registry."""
from __future__ import annotations

import re

import pytest

from nicer_stream.errors import SourceError
from sources import SCHEMES, open_source, parse_uri
from sources.base import SourceOptions


@pytest.mark.parametrize("start,stride,max_frames,n", [(0, 1, None, 7), (2, 3, None, 20), (5, 2, 3, 20), (9, 1, 4, 5)])
def test_selected_agrees_with_keeps(start, stride, max_frames, n):
    opts = SourceOptions(start=start, stride=stride, max_frames=max_frames)
    sel = opts.selected(n)
    kept = [i for i in range(n) if opts.keeps(i)]
    assert sel == kept[: max_frames or n]
    assert all(0 <= i < n for i in sel) and sel == sorted(set(sel))


def test_target_size():
    assert SourceOptions(max_side=320).target_size(1200, 680) == (320, 181)
    assert SourceOptions(max_side=320).target_size(480, 640) == (240, 320)
    assert SourceOptions(max_side=2000).target_size(1200, 680) == (1200, 680)  # never upsamples
    assert SourceOptions(scale=0.5).target_size(641, 480) == (320, 240)
    assert SourceOptions().target_size(17, 9) == (17, 9)


@pytest.mark.parametrize("kwargs", [dict(stride=0), dict(start=-1), dict(max_frames=0), dict(max_side=10, scale=0.5)])
def test_invalid_options_raise_one_line(kwargs):
    with pytest.raises(SourceError) as e:
        SourceOptions(**kwargs)
    assert "\n" not in str(e.value) and "--" in str(e.value)


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
