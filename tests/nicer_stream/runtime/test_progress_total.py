"""The run's progress against the log's length: each source's expected frame count honours
--start/--stride/--drop/--max-frames (it equals the frames it then gives), is None where the
length is unknown, and the status line reads it."""
from pathlib import Path

import cv2
import numpy as np
import pytest

from nicer_stream.runtime.progress import duration, frame_status
from sources import open_source
from sources.base import FrameSource, SourceOptions
from tests.sources.mcap_fixtures import foxglove_mcap, write_mp4
from nicer_stream.types import Intrinsics

INTR = Intrinsics(40.0, 40.0, 15.5, 11.5, 32, 24)


def frames(n: int) -> list[np.ndarray]:
    """`n` distinct (24, 32, 3) uint8 images (a block that moves)."""
    out = []
    for i in range(n):
        img = np.full((24, 32, 3), 40, np.uint8)
        img[4:12, i % 24: i % 24 + 8] = (200, 120, 30)
        out.append(img)
    return out


@pytest.fixture(scope="module")
def folder(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("imgs")
    for i, img in enumerate(frames(10)):
        cv2.imwrite(str(d / f"img{i}.png"), img)
    (d / "intrinsics.txt").write_text("40 40 15.5 11.5\n")
    return d


@pytest.mark.parametrize("opts, n", [
    (SourceOptions(), 10), (SourceOptions(start=1, stride=3), 3), (SourceOptions(stride=2, max_frames=3), 3),
    (SourceOptions(start=1, stride=3, drop=(4, 5)), 2), (SourceOptions(start=12), 0)],
    ids=["all", "start-stride", "stride-max", "drop", "past-end"])
def test_folder_total_is_the_frames_it_gives(folder, opts, n):
    src = open_source(f"folder:{folder}", opts)
    assert src.expected_frames() == len(list(src)) == n


def test_indexed_mcap_counts_its_topic_and_index_less_is_unknown(tmp_path):
    opts = SourceOptions(start=1, stride=2, max_frames=3)
    imgs = frames(9)
    indexed = open_source(f"mcap:{foxglove_mcap(tmp_path / 'a.mcap', imgs, INTR)}", opts)
    assert indexed.expected_frames() == len(list(indexed)) == 3  # frames 1, 3, 5 of 9 images (not the calibrations)
    assert open_source(f"mcap:{foxglove_mcap(tmp_path / 'b.mcap', imgs, INTR)}", SourceOptions(stride=4)).expected_frames() == 3
    bare = open_source(f"mcap:{foxglove_mcap(tmp_path / 'c.mcap', imgs, INTR, indexed=False)}", opts)
    assert bare.expected_frames() is None


def test_video_total_from_its_announced_count(tmp_path):
    path = write_mp4(tmp_path / "v.mp4", frames(8), fps=10.0)
    (tmp_path / "intrinsics.txt").write_text("40 40 15.5 11.5\n")
    src = open_source(f"video:{path}", SourceOptions(start=2, stride=3))
    assert src.expected_frames() == len(list(src)) == 2  # frames 2 and 5


def test_a_stream_of_unknown_length_has_no_total():
    class Stream(FrameSource):
        def _frames(self):
            yield from ()

    assert Stream().expected_frames() is None
    assert frame_status(120, None, 57.0) == "120 done, 2.11 frames/s"


def test_status_line_against_the_length():
    # 120 of 723 frames in 60 s: 2 frames/s, 603 to go -> 301.5 s
    assert frame_status(120, 723, 60.0) == "120/723, 17%, 2.00 frames/s, eta 5 min 02 s"
    assert frame_status(0, 723, 3.0) == "0/723, 0%, 0.00 frames/s, eta ?"  # the two-view start holds frames
    assert frame_status(6, 6, 2.0).endswith("100%, 3.00 frames/s, eta 0 s")
    assert [duration(s) for s in (0.4, 59.4, 61, 3600 * 2 + 300)] == ["0 s", "59 s", "1 min 01 s", "2 h 05 min"]
