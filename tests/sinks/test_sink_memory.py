"""What the sinks hold stays bounded on a long log: the sink worker's queue keeps no image of a
frame whose image no sink records, a live map update overtaken in the queue lets its map go
before the worker reaches it, and the frame -> time lookup keeps recent frames only."""
import gc
import threading
import weakref

import numpy as np

from nicer_stream.runtime.live_outputs import LiveMapOutputs
from nicer_stream.runtime.sink_worker import SinkWorker
from nicer_stream.slam.events import MapUpdated
from nicer_stream.types import Intrinsics
from sinks import MultiSink
from sinks.base import remember
from sinks.mcap_sink import McapSink
from sinks.options import SinkOptions
from sinks.rerun_sink import RerunSink

INTR = Intrinsics(20.0, 22.0, 7.5, 5.25, 16, 12)


class Image(np.ndarray):
    """An ndarray that a weak reference can follow."""


class Held:
    """A sink stand-in: records calls, holds each until `gate` opens."""

    def __init__(self, every: int, gate: threading.Event):
        self.every, self.gate, self.calls = every, gate, []

    def wants_image(self, index):
        return index % self.every == 0

    def log_frame(self, index, *a, **k):
        assert self.gate.wait(10)
        self.calls.append(("frame", index))

    def log_pose(self, index, *a, **k):
        assert self.gate.wait(10)
        self.calls.append(("pose", index))

    def close(self):
        pass


def test_the_worker_queues_no_image_for_frames_whose_image_is_not_recorded():
    gate = threading.Event()
    inner = Held(every=3, gate=gate)
    w = SinkWorker(inner)
    refs = []
    for i in range(7):
        rgb = np.zeros((12, 16, 3), np.float32).view(Image)
        refs.append(weakref.ref(rgb))
        w.log_frame(i, 0.1 * i, rgb, INTR, np.eye(4))
        del rgb
    gc.collect()
    held = [i for i, r in enumerate(refs) if r() is not None]
    assert held == [0, 3, 6]  # the queue holds the images the sink records, no others
    gate.set()
    w.close()
    assert inner.calls == [("frame", 0), ("pose", 1), ("pose", 2), ("frame", 3), ("pose", 4), ("pose", 5), ("frame", 6)]


def test_a_multisink_wants_an_image_any_of_its_sinks_records(tmp_path):
    a = RerunSink(tmp_path / "a.rrd", log_time=False, options=SinkOptions(images_every=2))
    b = McapSink(tmp_path / "b.mcap", options=SinkOptions(images_every=3))
    multi = MultiSink([a, b])
    assert [multi.wants_image(i) for i in range(7)] == [True, False, True, True, True, False, True]
    multi.close()


class Snapshot:
    """A map snapshot stand-in that a weak reference can follow."""


class FakeSlam:
    model, keyframes = "live", []

    def __init__(self):
        import torch

        self.poses = {i: torch.eye(4) for i in range(4)}
        self.snapshots = []

    def map_view(self):
        snap = Snapshot()
        self.snapshots.append(weakref.ref(snap))
        return snap, "beta"


def test_an_overtaken_live_update_lets_its_map_snapshot_go_before_the_worker_reaches_it():
    queued, slam = [], FakeSlam()
    live = LiveMapOutputs(sink=None, slam=slam, mesh_every=0, submit=queued.append)
    emitted = []
    live._emit = lambda event, intr, model, *rest: emitted.append((event.index, type(model).__name__))
    for i in (1, 2, 3):
        live(MapUpdated(i, (i,), 0.5, 10, 1.0), intr=None)
    gc.collect()
    assert [r() is not None for r in slam.snapshots] == [False, False, True]  # only the newest is held
    for fn in queued:
        fn()
    assert emitted == [(3, "Snapshot")] and live.skipped == 2


def test_the_frame_time_lookup_keeps_recent_frames_only():
    times: dict[int, int] = {}
    for i in range(10_000):
        remember(times, i, 1000 * i, limit=64)
    assert len(times) == 64 and min(times) == 10_000 - 64 and times[9_999] == 9_999_000
