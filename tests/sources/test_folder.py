"""folder: plain image folders (natural order, intrinsics.txt) and layout auto-detection."""
from __future__ import annotations

import logging

import cv2
import numpy as np
import pytest

from nicer_stream.errors import SourceError
from sources import open_source
from sources.base import SourceOptions
from sources.folder import natural_key
from sources.intrinsics_files import read_intrinsics_txt


@pytest.fixture
def images(replica_dir, tmp_path):
    """Folder with img1.png, img2.jpg, img10.png from three distinct real frames (48x85)."""
    d = tmp_path / "imgs"
    d.mkdir()
    means = []
    for name, i in (("img10.png", 0), ("img2.jpg", 5), ("img1.png", 10)):
        bgr = cv2.resize(cv2.imread(str(replica_dir / "results" / f"frame{i:06d}.jpg")), (85, 48))
        cv2.imwrite(str(d / name), bgr)
        means.append((name, cv2.imread(str(d / name))[..., ::-1].mean() / 255))
    (d / "notes.txt").write_text("not an image")
    return d, dict(means)


def test_natural_order_and_intrinsics_txt(images):
    d, means = images
    (d / "intrinsics.txt").write_text("# fx fy cx cy\n50.0 51.0 42.0 23.5  # at 85x48\n")
    src = open_source(f"folder:{d}")
    frames = list(src)
    assert len(src) == 3 and not src.has_gt_pose and src.name == "imgs"
    assert [f.name for f in frames] == ["img1", "img2", "img10"]
    assert [f.rgb.mean() for f in frames] == pytest.approx([means[n] for n in ("img1.png", "img2.jpg", "img10.png")], abs=1e-5)
    assert all(f.gt_pose is None and f.gt_depth is None for f in frames)
    k = frames[0].intrinsics
    assert (k.fx, k.fy, k.cx, k.cy, k.width, k.height) == (50.0, 51.0, 42.0, 23.5, 85, 48)
    assert [f.timestamp for f in frames] == pytest.approx([0, 1 / 30, 2 / 30])


def test_missing_intrinsics_and_override(images):
    d = images[0]
    with pytest.raises(SourceError, match="--intrinsics fx,fy,cx,cy"):
        open_source(f"folder:{d}")
    src = open_source(f"folder:{d}", SourceOptions(intrinsics=(40, 40, 42, 23.5), scale=2.0))
    k = next(iter(src)).intrinsics
    assert (k.width, k.height, k.fx) == (170, 96, 80) and k.cx == pytest.approx(2 * 42.5 - 0.5)


def test_corrupt_image_skipped(images, caplog):
    d = images[0]
    (d / "img2.jpg").write_bytes(b"\xff\xd8 truncated")
    src = open_source(f"folder:{d}", SourceOptions(intrinsics=(40, 40, 42, 23.5)))
    with caplog.at_level(logging.WARNING):
        frames = list(src)
    assert [f.name for f in frames] == ["img1", "img10"] and [f.index for f in frames] == [0, 1]
    assert src.skipped_frames == 1 and any("img2.jpg" in r.getMessage() for r in caplog.records)


def test_bad_intrinsics_txt(tmp_path):
    (tmp_path / "intrinsics.txt").write_text("500 500 320\n")
    with pytest.raises(SourceError, match="four numbers"):
        read_intrinsics_txt(tmp_path / "intrinsics.txt")


def test_detects_dataset_layouts(replica_dir, tum_dir):
    rep = open_source(f"folder:{replica_dir}", SourceOptions(max_frames=2, max_side=64))
    assert len(rep) == 2 and rep.has_gt_pose and next(iter(rep)).gt_depth is not None
    tum = open_source(f"folder:{tum_dir}")
    assert len(tum) == 4 and tum.has_gt_pose and next(iter(tum)).intrinsics.fx == 535.4


def test_empty_and_missing(tmp_path):
    with pytest.raises(SourceError, match="does not exist"):
        open_source(f"folder:{tmp_path / 'nothing'}")
    with pytest.raises(SourceError, match="expected"):
        open_source(f"folder:{tmp_path}")
    f = tmp_path / "a.png"
    f.write_bytes(b"")
    with pytest.raises(SourceError, match="not a folder"):
        open_source(f"folder:{f}")


def test_natural_key():
    names = ["f10.png", "f2.png", "F1.png", "f1b.png"]
    assert sorted(names, key=natural_key) == ["F1.png", "f1b.png", "f2.png", "f10.png"]
