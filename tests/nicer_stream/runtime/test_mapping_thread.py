"""The mapping worker: jobs run on their own thread with their own torch thread count, tracking
goes on against a snapshot while a job runs, errors reach the caller."""
import json
import threading

import pytest
import torch

from nicer_stream.config import load
from nicer_stream.io import output_dir as od
from nicer_stream.runtime.mapping_thread import MappingThread, split_threads
from nicer_stream.runtime.slam_run import RunRequest, run_slam
from nicer_stream.slam.events import FrameTracked, MapUpdated
from nicer_stream.slam.map_jobs import MapJob
from nicer_stream.slam.system import SlamSystem
from sources import open_source
from sources.base import SourceOptions


def _job(closing=False):
    return MapJob(0, (0,), [], {}, 1, frozenset(), "test", closing)


@pytest.mark.parametrize("cores, split", [(1, (1, 1)), (2, (1, 1)), (3, (1, 2)), (8, (4, 4))])
def test_cores_are_split_between_tracking_and_mapping(cores, split):
    assert split_threads(cores) == split


def test_a_job_runs_on_another_thread_with_its_own_torch_thread_count():
    main_threads = torch.get_num_threads()
    ex = MappingThread(threads=1, threads_alone=3)
    seen = []
    ex.submit(_job(), lambda j: seen.append((threading.current_thread().name, torch.get_num_threads())) or "r")
    assert ex.drain() == ["r"] and not ex.busy()
    ex.submit(_job(closing=True), lambda j: seen.append((threading.current_thread().name, torch.get_num_threads())))
    ex.drain()
    ex.close()
    assert seen[0][0].startswith("mapping") and [s[1] for s in seen] == [1, 3]
    assert torch.get_num_threads() == main_threads


def test_a_job_error_reaches_the_caller_and_one_job_is_in_flight_at_a_time():
    ex, release = MappingThread(threads=1), threading.Event()
    ex.submit(_job(), lambda j: release.wait(5) and 1 / 0)
    with pytest.raises(RuntimeError, match="in flight"):
        ex.submit(_job(), lambda j: None)
    assert ex.busy() and ex.poll() == []
    release.set()
    with pytest.raises(ZeroDivisionError):
        ex.drain()
    ex.close()


def test_tracking_goes_on_while_a_mapping_call_runs(tiny_config):
    cfg = load("fast", tiny_config)  # mapping every 2 frames
    ex, release, started = MappingThread(threads=1), threading.Event(), threading.Event()
    slam = SlamSystem(cfg, mapping=ex)
    run_job = slam.maps.run

    def held(job):  # the first scheduled call holds the worker until the test lets it go
        started.set()
        release.wait(30)
        return run_job(job)

    slam.maps.run = held
    frames = list(open_source("synthetic:room?frames=7", SourceOptions(max_side=32)))
    events = []
    for f in frames[:3]:  # frame 2 submits the call
        events += slam.step(f.without_ground_truth())
    assert started.wait(30) and ex.busy()
    assert slam.tracker.model is not slam.model  # tracking reads the snapshot of the first mapping
    for f in frames[3:5]:  # tracked while the call runs; frame 4's call is deferred
        events += slam.step(f.without_ground_truth())
    assert [e.index for e in events if isinstance(e, FrameTracked)] == [0, 1, 2, 3, 4]
    assert not any(isinstance(e, MapUpdated) and e.background for e in events)
    release.set()
    slam.maps.run = run_job
    assert ex.wait(60)  # the held call ends before frame 5: the deferred one then starts there
    for f in frames[5:]:
        events += slam.step(f.without_ground_truth())
    events += slam.finish()
    ex.close()
    maps = [e for e in events if isinstance(e, MapUpdated)]
    assert [e.version for e in maps] == list(range(1, len(maps) + 1)) == list(range(1, slam.map_version + 1))
    assert maps[1].index == 2 and maps[1].background  # the held call, applied after the release
    assert any(e.index > 4 and e.background for e in maps[2:])  # the deferred call ran
    assert maps[-1].window and not maps[-1].background  # the closing call: the caller waited
    assert len(slam.trajectory()[1]) == 7


def test_async_run_reports_its_runtime_and_pose_latency(tmp_path, tiny_config):
    out = run_slam(RunRequest(source="synthetic:room?frames=5", out_dir=tmp_path / "out", priors="none", mapping_worker="on",
                              config_file=str(tiny_config))).out_dir
    stats = json.loads((out / od.SUMMARY_FILE).read_text())["stats"]
    assert stats["runtime"].startswith("async") and stats["map_versions"] >= 2
    assert 0 < stats["pose_latency_median_s"] <= stats["pose_latency_p95_s"]
    assert 0 < stats["pose_latency_after_startup_median_s"] <= stats["pose_latency_after_startup_p95_s"]
