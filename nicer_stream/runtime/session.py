"""`RunSession`: one `nicer-stream run`, source -> priors -> SLAM -> sinks -> output directory."""
from __future__ import annotations

import logging
import math
import time
from pathlib import Path
from typing import TYPE_CHECKING

import torch

from nicer_stream import config as config_mod
from nicer_stream.errors import UserError, one_line
from nicer_stream.runtime.allocator import retain_freed_memory
from nicer_stream.runtime.final_outputs import write_outputs
from nicer_stream.runtime.frame_book import FrameBook
from nicer_stream.runtime.frame_priors import fuses_stereo, make_engine
from nicer_stream.runtime.frame_reader import ReadAhead
from nicer_stream.runtime.live_outputs import LiveMapOutputs
from nicer_stream.runtime.mapping_thread import MappingThread
from nicer_stream.runtime.matmul_backend import enable_onednn_matmul
from nicer_stream.runtime.pacer import Pacer
from nicer_stream.runtime.prior_stage import PriorStage
from nicer_stream.runtime.progress import Progress, frame_status
from nicer_stream.runtime.render_picker import RenderPicker
from nicer_stream.runtime.run_request import RunOutcome, RunRequest
from nicer_stream.runtime.run_state import RunState
from nicer_stream.runtime.run_summary import final_line, write_run_summary
from nicer_stream.runtime.sink_worker import SinkWorker
from nicer_stream.runtime.source_setup import open_configured
from nicer_stream.runtime.stage_timer import StageTimer
from nicer_stream.runtime.stop import StopSignals
from nicer_stream.runtime.thread_plan import ThreadPlan, renders_on_sink_worker
from nicer_stream.slam.events import FrameTracked, KeyframeAdded, MapUpdated, TrackingWarning
from nicer_stream.slam.system import SlamSystem
from sinks import make_sink

if TYPE_CHECKING:
    from nicer_stream.types import Frame

log = logging.getLogger(__name__)

# Mapping calls report on stderr after their first iteration, then at most this often.
MAPPING_PROGRESS_EVERY_S = 3.0


def report_error(e: Exception) -> str:
    """The error in one line on the console (its traceback at debug level); returns that line."""
    error = one_line(e)
    log.debug("the run stopped on an error", exc_info=True)
    print(f"error: {error}; writing what was computed so far", flush=True)
    return error


class RunSession(RunState):
    """Opens the source, priors, SLAM and sinks of a run; `run()` feeds the frames, handles the
    SLAM's events, stops on a signal or an error and writes every output computed so far."""

    def __init__(self, req: RunRequest, stop: StopSignals) -> None:
        self.req, self.stop = req, stop
        self.cfg = cfg = config_mod.load(req.preset, req.config_file)
        torch.manual_seed(cfg.seed)
        retain_freed_memory()
        enable_onednn_matmul()
        self.timer = StageTimer()
        self.threads = ThreadPlan.choose(req.mapping_worker, req.sync, req.device)
        print(f"opening {req.source} (preset {cfg.preset}, priors {req.priors}, device {req.device}); "
              f"{self.threads.description}; mapping progress on stderr", flush=True)
        self.source, _ = open_configured(req.source, req.source_opts, cfg)
        self.out = Path(req.out_dir)
        self.out.mkdir(parents=True, exist_ok=True)
        self.engine = make_engine(req.priors, req.flow, req.device, seed=cfg.seed)
        if self.engine.depth_normal.auto_reason:
            print(self.engine.depth_normal.auto_reason, flush=True)
        self.stage = PriorStage(self.engine)
        self.worker = (MappingThread(self.threads.map_threads, threads_alone=self.threads.all_threads)
                       if self.threads.use_worker else None)
        self.failed = False  # an error ended the loop: the mapping call in hand stops too
        self.error: str | None = None
        self.early = False  # stopped or failed: no renders; summary.json says interrupted
        self.slam = self._open_slam()
        self._open_sinks()
        self.pacer = Pacer(req.realtime)
        self.book = FrameBook(RenderPicker(max(1, req.render_every), max(0, req.max_renders)))
        self.total = self.source.expected_frames()  # None for streams of unknown length
        self.t_start = time.perf_counter()
        self.reader = self.source if req.sync else ReadAhead(self.source)  # read and decoded on its own thread

    def _open_slam(self) -> SlamSystem:
        req, name = self.req, self.engine.depth_normal.name
        return SlamSystem(self.cfg, req.device,
                          progress=None if req.quiet else lambda label: Progress(label, MAPPING_PROGRESS_EVERY_S),
                          stereo=name == "stereo", should_stop=lambda: self.stop.requested or self.failed,
                          mapping=self.worker, fuse_mono=fuses_stereo(self.cfg, name))

    def _open_sinks(self) -> None:
        """The sink (on its worker unless --sync) and the live map outputs, rendered on the sink
        worker when a core is free, else on this thread."""
        req = self.req
        sink = make_sink(list(req.sinks)) if req.sinks else None
        self.live = None
        if sink is not None and not req.sync:  # sink calls on the sink worker
            sink = SinkWorker(sink)
        if isinstance(sink, SinkWorker) and renders_on_sink_worker(req.device, self.threads.all_threads):
            self.live = LiveMapOutputs(sink.sink, self.slam, req.live_mesh_every, submit=sink.submit)
        elif sink is not None:  # rendered on this thread (--sync, or no core to spare), logged through `sink`
            self.live = LiveMapOutputs(sink, self.slam, req.live_mesh_every)
        self.sink = sink

    def status(self) -> str:
        """[done/total, %, frames per second, ETA, map version, queue depths] for the per-frame line."""
        queues = ""
        if not self.req.sync:  # frames read ahead, sink calls waiting, whether mapping is running
            slam = self.slam
            queues = (f", map v{slam.map_version}{'+' if slam.mapping.busy() else ''}, "
                      f"queued {self.reader.depth} frames / "
                      f"{self.sink.pending if isinstance(self.sink, SinkWorker) else 0} sink calls")
        return f"[{frame_status(self.book.reported, self.total, time.perf_counter() - self.t_start)}{queues}]"

    def run(self) -> RunOutcome:
        """Feed every frame, then write the outputs; the outcome says how the run ended."""
        try:
            self._feed_all()
            self._wind_down()
            write_outputs(self)
        finally:
            self._close()
        self.early = self.early or self.stop.requested  # a stop during the renders or the mesh
        print(final_line(self, write_run_summary(self)), flush=True)
        code = self.stop.exit_code if self.stop.requested else (1 if self.error is not None else 0)
        return RunOutcome(self.out, code, self.error)

    def _feed_all(self) -> None:
        """Every frame through the SLAM and its closing call; a stop or an error ends it early."""
        try:
            for frame in self.reader:
                if self.stop.requested:
                    break
                if self.pacer.drop(frame.timestamp):
                    continue
                self._feed(frame)
            if not self.stop.requested:
                events = self._timed(self.slam.finish)[0]
                updates = [e for e in events if isinstance(e, MapUpdated)]
                # The closing update's map is the final one: the outputs render its last frame at
                # full size and log that, rather than a half-size live render here.
                self.handle(events, 0.0, None, unrendered=updates[-1] if updates and not self.stop.requested else None)
        except KeyboardInterrupt:  # where the handlers could not be installed (not the main thread)
            self.stop.request()
        except Exception as e:  # a stage failed: keep what was computed, report it in one line
            self.error, self.failed = report_error(e), True

    def _feed(self, frame: Frame) -> None:
        """One frame: its priors, the SLAM's step, the events."""
        self.book.read(frame, self.slam.map_version > 0)
        with self.timer.stage("priors"):
            pri = self.stage(frame, flows=False)
        # Flows when the SLAM asks for them (most frames of a log never become keyframes).
        events, step_s = self._timed(lambda: self.slam.step(frame.without_ground_truth(), pri, self.stage.deferred_flows))
        self.book.fed_to_slam(frame)
        if not any(isinstance(e, FrameTracked) and e.index == frame.index for e in events):
            self.say(f"frame {frame.index:5d}  held for the two-view start  {self.status()}")
        self.handle(events, step_s, frame)

    def _timed(self, call):
        """Run one SLAM call -> (events, seconds); its mapping calls' seconds are booked as
        mapping, the rest (tracking, flow start, the two-view start's set-up) as tracking."""
        slam, seconds = self.slam, self.timer.seconds
        t0, waited = time.perf_counter(), slam.mapping_wait_s
        events = call()
        elapsed = time.perf_counter() - t0
        # Mapping: the seconds of the calls that finished (on the worker they overlap tracking);
        # tracking: this call's seconds except those spent in or waiting for mapping.
        seconds.mapping += sum(e.seconds for e in events if isinstance(e, MapUpdated))
        seconds.tracking += max(elapsed - (slam.mapping_wait_s - waited), 0.0)
        track = self.threads.track_threads
        if self.worker is not None and slam.map_version >= 1 and torch.get_num_threads() != track:
            torch.set_num_threads(track)  # the start-up is over: the worker has the rest
        return events, elapsed

    def handle(self, events: list, step_s: float, frame: Frame | None, unrendered: MapUpdated | None = None) -> None:
        """Progress line, kept renders and sink logging for each event (no live render of the
        `unrendered` map update)."""
        # Several frames in one step (the two-view start replays the held frames): each
        # line then shows that frame's own tracking time.
        replay = sum(isinstance(e, FrameTracked) for e in events) > 1
        for e in events:
            if isinstance(e, KeyframeAdded):
                self.stage.add_keyframe(self.book.waiting.get(e.index, frame))
            if isinstance(e, TrackingWarning) and self.sink is not None:  # (the console has it from the log)
                with self.timer.stage("sinks"):
                    self.sink.log_warning(e.index, e.kind, e.message)
            if isinstance(e, MapUpdated) and self.live is not None and self.book.intr is not None:
                with self.timer.stage("sinks"):
                    self.live(e, self.book.intr, render=e is not unrendered)
            if isinstance(e, FrameTracked):
                self._tracked(e, step_s, frame, replay)

    def _tracked(self, e: FrameTracked, step_s: float, frame: Frame | None, replay: bool) -> None:
        """A pose event: the frame's line and its sink logs."""
        f = self.book.waiting.pop(e.index, frame)
        if f is None:  # a later pose of a frame already reported (refined before the closing call)
            self.say(f"frame {e.index:5d}  refined against the map: track loss {e.loss:.4f}")
            return
        self.book.pose_reported(e.index, f)
        lost = f" LOST ({e.lost})" if e.lost else ""
        secs = f"{e.seconds:.1f} s tracking" if replay else f"{step_s:.1f} s"
        how = f"track loss {e.loss:.4f}" if math.isfinite(e.loss) else "frontend pose"
        self.say(f"frame {e.index:5d}  {how}  {secs}{lost}  {self.status()}")
        if self.sink is not None:
            with self.timer.stage("sinks"):
                if e.lost:
                    self.sink.log_warning(e.index, "lost", e.lost)
                self.sink.log_frame(e.index, e.timestamp, f.rgb, f.intrinsics, e.T_world_cam,
                                    gt_T_world_cam=f.gt_pose, timestamp_ns=f.timestamp_ns)
                if math.isfinite(e.loss):
                    self.sink.log_scalars(e.index, {"tracking_loss": e.loss, "seconds": step_s})

    def _wind_down(self) -> None:
        """After the loop: the mapping call in hand applied, threads restored, the reader closed,
        the stop reported, the stage seconds settled."""
        slam = self.slam
        if slam.model is not None:  # stopped early: the mapping call in hand ends and is applied
            try:
                slam.wait_for_mapping()
            except Exception as e:
                self.error = self.error or report_error(e)
        torch.set_num_threads(self.threads.all_threads)
        if isinstance(self.reader, ReadAhead):
            self.reader.close()  # a stop or an error left frames unread
        if slam.model is None and self.error is None and not self.stop.requested:
            raise UserError(f"source {self.req.source} gave no usable frames")
        if self.stop.requested:
            print(f"stopped by {self.stop.reason}: writing what was computed so far", flush=True)
        self.early = self.stop.requested or self.error is not None
        if not self.early:
            self.book.keep_last()
        self.timer.seconds.frontend = slam.frontend_seconds
        if slam.stereo is not None:  # computed inside SLAM calls (booked as tracking): a prior stage
            self.timer.seconds.tracking -= slam.stereo.seconds
            self.timer.seconds.priors += slam.stereo.seconds

    def _close(self) -> None:
        """The reader, the mapping worker and the sink closed, whatever happened."""
        if isinstance(self.reader, ReadAhead):
            self.reader.close()
        if self.worker is not None:
            self.worker.close()
        if self.sink is not None:
            try:
                self.sink.close()
            except Exception as e:  # a sink failed (already logged): the files are written
                self.error = self.error or report_error(e)
