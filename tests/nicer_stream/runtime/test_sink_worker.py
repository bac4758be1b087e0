"""The sink worker: calls made in order on its own thread while the caller goes on; a failing
sink stops receiving calls and its error comes back at close; live map updates a newer one
overtook are skipped."""
import threading

import numpy as np
import pytest

from nicer_stream.runtime.live_outputs import LiveMapOutputs
from nicer_stream.runtime.sink_worker import SinkWorker
from nicer_stream.slam.events import MapUpdated


class Recorder:
    """Records calls; `gate`, when set, holds every call until it opens."""

    def __init__(self, gate=None, fail_at=None):
        self.calls, self.threads, self.closed = [], set(), False
        self.gate, self.fail_at = gate, fail_at

    def log_scalars(self, index, values):
        if self.gate is not None:
            assert self.gate.wait(10)
        if index == self.fail_at:
            raise OSError("disk full")
        self.calls.append(index)
        self.threads.add(threading.current_thread().name)

    def close(self):
        self.closed = True


def test_calls_are_made_in_order_on_the_worker_while_the_caller_goes_on():
    gate = threading.Event()
    inner = Recorder(gate)
    w = SinkWorker(inner)
    for i in range(5):
        w.log_scalars(i, {"loss": float(i)})  # returns at once: the sink is held
    assert inner.calls == [] and w.pending >= 4
    gate.set()
    w.close()
    assert inner.calls == list(range(5)) and inner.threads == {"sinks"} and inner.closed


def test_a_failing_sink_gets_no_further_calls_and_close_reports_it():
    inner = Recorder(fail_at=2)
    w = SinkWorker(inner)
    for i in range(5):
        w.log_scalars(i, {})
    with pytest.raises(OSError, match="disk full"):
        w.close()
    assert inner.calls == [0, 1] and inner.closed
    w.close()  # idempotent: the error was reported once


class FakeSlam:
    """What LiveMapOutputs reads of the SLAM system."""

    model = "live"
    keyframes: list = []
    poses: dict = {}

    def __init__(self):
        import torch

        self.poses = {i: torch.eye(4) for i in range(4)}

    def map_view(self):
        return "model", "beta"

    def trajectory(self):
        return [0.0], [np.eye(4)]


def test_live_updates_overtaken_in_the_queue_are_skipped_and_the_newest_is_logged():
    queued = []
    live = LiveMapOutputs(sink=None, slam=FakeSlam(), mesh_every=0, submit=queued.append)
    emitted = []
    live._emit = lambda event, *rest: emitted.append(event.index)
    for i in (1, 2, 3):
        live(MapUpdated(i, (i,), 0.5, 10, 1.0), intr=None)
    for fn in queued:  # the worker gets to them only now
        fn()
    assert emitted == [3] and live.skipped == 2
    live(MapUpdated(0, (0,), 0.5, 10, 1.0), intr=None)
    queued[-1]()
    assert emitted == [3, 0]


def test_without_a_spare_core_live_renders_run_on_the_slam_thread_and_logging_on_the_worker(monkeypatch):
    import nicer_stream.runtime.live_outputs as lo
    import nicer_stream.runtime.thread_plan as sr
    from nicer_stream.types import Intrinsics

    monkeypatch.setattr(sr, "available_cores", lambda: 2)
    assert not sr.renders_on_sink_worker("cpu", 2)
    assert sr.renders_on_sink_worker("cpu", 1) and sr.renders_on_sink_worker("cuda:0", 2)

    render_threads = []

    class View:
        rgb, depth, normal = np.zeros((2, 2, 3)), np.zeros((2, 2)), np.zeros((2, 2, 3))

    def render(*args, **kwargs):
        render_threads.append(threading.current_thread().name)
        return View()

    class Sink(Recorder):
        def log_map_render(self, index, *args):
            self.calls.append(("render", index))
            self.threads.add(threading.current_thread().name)

    class NoVoxels:
        def voxel_betas(self):
            return np.zeros((0, 3)), np.zeros(0)

    monkeypatch.setattr(lo, "render_image", render)
    slam = FakeSlam()
    slam.cfg = type("Cfg", (), {"render": None})()
    slam.map_view = lambda: ("model", NoVoxels())
    inner = Sink()
    worker = SinkWorker(inner)
    live = LiveMapOutputs(worker, slam, mesh_every=0)  # as the runtime builds it without a spare core
    intr = Intrinsics(fx=2.0, fy=2.0, cx=1.0, cy=1.0, width=4, height=4)
    live(MapUpdated(1, (1,), 0.5, 10, 1.0), intr=intr)
    worker.close()
    assert render_threads == [threading.current_thread().name]
    assert ("render", 1) in inner.calls and inner.threads == {"sinks"}
