"""`nicer-stream run`: source -> priors -> SLAM -> sinks -> output directory."""
from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch

from nicer_stream import config as config_mod
from nicer_stream.errors import UserError, one_line
from nicer_stream.runtime.allocator import retain_freed_memory
from nicer_stream.runtime.matmul_backend import enable_onednn_matmul
from nicer_stream.io.scene_file import save_scene
from nicer_stream.runtime.frame_priors import fuses_stereo, make_engine, provider_names
from nicer_stream.runtime.live_outputs import MESH_RESOLUTION, LiveMapOutputs, coarse_mesh
from nicer_stream.runtime.frame_reader import ReadAhead
from nicer_stream.runtime.mapping_thread import MappingThread, available_cores, split_threads
from nicer_stream.runtime.sink_worker import SinkWorker
from nicer_stream.runtime.pacer import Pacer
from nicer_stream.runtime.prior_stage import PriorStage
from nicer_stream.runtime.progress import Progress, frame_status
from nicer_stream.runtime.render_picker import RenderPicker
from nicer_stream.runtime.run_outputs import write_mesh, write_summary, write_trajectory
from nicer_stream.runtime.scene_export import MeshAborted, save_render, scene_mesh
from nicer_stream.runtime.stage_timer import StageTimer
from nicer_stream.runtime.stop import StopSignals
from nicer_stream.render.renderer import render_image
from nicer_stream.slam.events import FrameTracked, KeyframeAdded, MapUpdated, TrackingWarning
from nicer_stream.slam.system import SlamSystem
from nicer_stream.runtime.source_setup import intrinsics_dict, open_configured
from sources.base import SourceOptions

log = logging.getLogger(__name__)

# Mapping calls report on stderr after their first iteration, then at most this often.
MAPPING_PROGRESS_EVERY_S = 3.0


@dataclass(frozen=True)
class RunRequest:
    """What `nicer-stream run` was asked to do."""

    source: str
    out_dir: Path
    priors: str = "auto"
    flow: str | None = None
    preset: str = "fast"
    config_file: str | None = None
    sinks: tuple[str, ...] = ()
    device: str = "cpu"
    realtime: bool = False
    render_every: int = 10
    """Render (and evaluate) every N-th frame at the end, and the last one."""
    max_renders: int = 20
    """At most this many of those (0: no cap): on longer logs the stride doubles until they fit
    (`runtime/render_picker.py`), so the end of a run does not grow with its length."""
    quiet: bool = False
    """No per-frame lines and no mapping progress: errors and the final summary only."""
    live_mesh_every: int = 5
    """With a sink: a coarse mesh every this many map updates (0: only the final mesh)."""
    sync: bool = False
    """Everything in one thread, in order (deterministic under a seed); default: frames read and
    sinks called on threads of their own, mapping as `mapping_worker` says."""
    mapping_worker: str = "auto"
    """'on': mapping calls on a worker thread, tracking against the last published map; 'off':
    mapping inline with tracking; 'auto': on with a GPU or >= 4 cores. Measured on 2 cores
    (docs/runtime.md): the worker made the Replica run 11% slower, the stages being memory-bound."""
    source_opts: SourceOptions = field(default_factory=SourceOptions)


@dataclass(frozen=True)
class RunOutcome:
    """Where the outputs are and how the run ended."""

    out_dir: Path
    exit_code: int = 0
    """0; 130 / 143 after a stop by SIGINT / SIGTERM; 1 after an error inside a stage."""
    error: str | None = None
    """The one-line error that ended the run early (also in summary.json)."""



def mapping_on_worker(req: RunRequest) -> bool:
    """Whether mapping runs on its own thread (RunRequest.mapping_worker)."""
    if req.mapping_worker not in ("auto", "on", "off"):
        raise UserError(f"--mapping-worker must be auto, on or off, got {req.mapping_worker!r}")
    if req.sync or req.mapping_worker == "off":
        return False
    return req.mapping_worker == "on" or req.device.startswith("cuda") or available_cores() >= 4


def renders_on_sink_worker(device: str, slam_threads: int) -> bool:
    """Whether the live map renders run on the sink worker (a GPU, or a core the SLAM thread's
    `slam_threads` intra-op threads leave free) or on the SLAM thread. On a CPU with no spare
    core the worker's one render thread and the SLAM thread's two made three busy threads on
    two cores, and the SLAM thread's parallel regions waited for whichever was descheduled:
    `make demo` 205 s without a sink, 228-237 s with one, for ~20 s of renders
    (docs/decisions.md)."""
    return device.startswith("cuda") or available_cores() > slam_threads


def _report_error(e: Exception) -> str:
    """The error in one line on the console (its traceback at debug level); returns that line."""
    error = one_line(e)
    log.debug("the run stopped on an error", exc_info=True)
    print(f"error: {error}; writing what was computed so far", flush=True)
    return error


def run_slam(req: RunRequest) -> RunOutcome:
    """Run SLAM over the source and write the output directory. A stop (Ctrl-C, SIGTERM) or an
    error inside a stage ends the loop early; every output computed so far is still written."""
    with StopSignals() as stop:
        return _run(req, stop)


def _run(req: RunRequest, stop: StopSignals) -> RunOutcome:
    cfg = config_mod.load(req.preset, req.config_file)
    torch.manual_seed(cfg.seed)
    retain_freed_memory()
    enable_onednn_matmul()
    timer = StageTimer()
    all_threads = torch.get_num_threads()
    track_threads, map_threads = split_threads()
    use_worker = mapping_on_worker(req)
    runtime = ("sync (one thread)" if req.sync else
               f"async (mapping worker; tracking {track_threads} + mapping {map_threads} intra-op threads)" if use_worker
               else "async (reader and sink threads; mapping inline with tracking)")
    print(f"opening {req.source} (preset {cfg.preset}, priors {req.priors}, device {req.device}); "
          f"{runtime}; mapping progress on stderr", flush=True)
    source, _ = open_configured(req.source, req.source_opts, cfg)
    out = Path(req.out_dir)
    out.mkdir(parents=True, exist_ok=True)
    engine = make_engine(req.priors, req.flow, req.device)
    if engine.depth_normal.auto_reason:
        print(engine.depth_normal.auto_reason, flush=True)
    stage = PriorStage(engine)
    worker = MappingThread(map_threads, threads_alone=all_threads) if use_worker else None
    slam = SlamSystem(cfg, req.device,
                      progress=None if req.quiet else lambda label: Progress(label, MAPPING_PROGRESS_EVERY_S),
                      stereo=engine.depth_normal.name == "stereo", should_stop=lambda: stop.requested or failed,
                      mapping=worker, fuse_mono=fuses_stereo(cfg, engine.depth_normal.name))
    from sinks import make_sink

    sink = make_sink(list(req.sinks)) if req.sinks else None
    live = None
    if sink is not None and not req.sync:  # sink calls on the sink worker
        sink = SinkWorker(sink)
    if isinstance(sink, SinkWorker) and renders_on_sink_worker(req.device, all_threads):
        live = LiveMapOutputs(sink.sink, slam, req.live_mesh_every, submit=sink.submit)
    elif sink is not None:  # rendered on this thread (--sync, or no core to spare), logged through `sink`
        live = LiveMapOutputs(sink, slam, req.live_mesh_every)
    pacer = Pacer(req.realtime)
    n, intr, kept, last, waiting, error = 0, None, {}, None, {}, None
    picker = RenderPicker(max(1, req.render_every), max(0, req.max_renders))
    total = source.expected_frames()  # None for streams of unknown length
    done, t_start = 0, time.perf_counter()
    reader = source if req.sync else ReadAhead(source)  # read and decoded on its own thread
    failed = False  # an error ended the loop: the mapping call in hand stops too
    read_at: dict[int, tuple[float, bool]] = {}  # frame index -> (when the source gave it, a map existed)
    latency: list[tuple[float, bool]] = []  # (seconds from frame read to its pose event, read after the start-up)

    def say(text: str) -> None:
        if not req.quiet:
            print(text, flush=True)

    def status() -> str:
        """[done/total, %, frames per second, ETA, map version, queue depths] for the per-frame line."""
        queues = ""
        if not req.sync:  # frames read ahead, sink calls waiting, whether mapping is running
            queues = (f", map v{slam.map_version}{'+' if slam.mapping.busy() else ''}, "
                      f"queued {reader.depth} frames / {sink.pending if isinstance(sink, SinkWorker) else 0} sink calls")
        return f"[{frame_status(done, total, time.perf_counter() - t_start)}{queues}]"

    def timed(call):
        """Run one SLAM call -> (events, seconds); its mapping calls' seconds are booked as
        mapping, the rest (tracking, flow start, the two-view start's set-up) as tracking."""
        t0, waited = time.perf_counter(), slam.mapping_wait_s
        events = call()
        elapsed = time.perf_counter() - t0
        # Mapping: the seconds of the calls that finished (on the worker they overlap tracking);
        # tracking: this call's seconds except those spent in or waiting for mapping.
        timer.seconds.mapping += sum(e.seconds for e in events if isinstance(e, MapUpdated))
        timer.seconds.tracking += max(elapsed - (slam.mapping_wait_s - waited), 0.0)
        if worker is not None and slam.map_version >= 1 and torch.get_num_threads() != track_threads:
            torch.set_num_threads(track_threads)  # the start-up is over: the worker has the rest
        return events, elapsed

    def handle(events, step_s: float, frame, unrendered: MapUpdated | None = None) -> None:
        """Progress line, kept renders and sink logging for each event (no live render of the
        `unrendered` map update)."""
        nonlocal last, done
        # Several frames in one step (the two-view start replays the held frames): each
        # line then shows that frame's own tracking time.
        replay = sum(isinstance(e, FrameTracked) for e in events) > 1
        for e in events:
            if isinstance(e, KeyframeAdded):
                stage.add_keyframe(waiting.get(e.index, frame))
            if isinstance(e, TrackingWarning) and sink is not None:  # (the console has it from the log)
                with timer.stage("sinks"):
                    sink.log_warning(e.index, e.kind, e.message)
            if isinstance(e, MapUpdated) and live is not None and intr is not None:
                with timer.stage("sinks"):
                    live(e, intr, render=e is not unrendered)
            if isinstance(e, FrameTracked):
                f = waiting.pop(e.index, frame)
                if f is None:  # a later pose of a frame already reported (refined before the closing call)
                    say(f"frame {e.index:5d}  refined against the map: track loss {e.loss:.4f}")
                    continue
                if e.index in read_at:
                    t_read, steady = read_at.pop(e.index)
                    latency.append((time.perf_counter() - t_read, steady))
                keep, released = picker.offer(e.index)
                kept[e.index] = f.rgb if keep else None
                for i in released:  # a long log: the stride doubled, their images go
                    kept[i] = None
                last = (e.index, f.rgb)
                lost = f" LOST ({e.lost})" if e.lost else ""
                secs = f"{e.seconds:.1f} s tracking" if replay else f"{step_s:.1f} s"
                done += 1
                how = f"track loss {e.loss:.4f}" if math.isfinite(e.loss) else "frontend pose"
                say(f"frame {e.index:5d}  {how}  {secs}{lost}  {status()}")
                if sink is not None:
                    with timer.stage("sinks"):
                        if e.lost:
                            sink.log_warning(e.index, "lost", e.lost)
                        sink.log_frame(e.index, e.timestamp, f.rgb, f.intrinsics, e.T_world_cam,
                                       gt_T_world_cam=f.gt_pose, timestamp_ns=f.timestamp_ns)
                        if math.isfinite(e.loss):
                            sink.log_scalars(e.index, {"tracking_loss": e.loss, "seconds": step_s})

    try:
        try:
            for frame in reader:
                if stop.requested:
                    break
                if pacer.drop(frame.timestamp):
                    continue
                read_at[frame.index] = (time.perf_counter(), slam.map_version > 0)
                intr = frame.intrinsics
                with timer.stage("priors"):
                    pri = stage(frame, flows=False)
                # Flows when the SLAM asks for them (most frames of a log never become keyframes).
                events, step_s = timed(lambda: slam.step(frame.without_ground_truth(), pri, stage.deferred_flows))
                n += 1
                waiting[frame.index] = frame  # until its pose event (the two-view start holds frames)
                if not any(isinstance(e, FrameTracked) and e.index == frame.index for e in events):
                    say(f"frame {frame.index:5d}  held for the two-view start  {status()}")
                handle(events, step_s, frame)
            if not stop.requested:
                events = timed(slam.finish)[0]
                updates = [e for e in events if isinstance(e, MapUpdated)]
                # The closing update's map is the final one: the outputs below render its last
                # frame at full size and log that, rather than a half-size live render here.
                handle(events, 0.0, None, unrendered=updates[-1] if updates and not stop.requested else None)
        except KeyboardInterrupt:  # where the handlers could not be installed (not the main thread)
            stop.request()
        except Exception as e:  # a stage failed: keep what was computed, report it in one line
            error, failed = _report_error(e), True
        if slam.model is not None:  # stopped early: the mapping call in hand ends and is applied
            try:
                slam.wait_for_mapping()
            except Exception as e:
                error = error or _report_error(e)
        torch.set_num_threads(all_threads)
        if isinstance(reader, ReadAhead):
            reader.close()  # a stop or an error left frames unread
        if slam.model is None and error is None and not stop.requested:
            raise UserError(f"source {req.source} gave no usable frames")
        if stop.requested:
            print(f"stopped by {stop.reason}: writing what was computed so far", flush=True)
        early = stop.requested or error is not None
        if last is not None and not early:  # the last frame is always rendered, as in `map`
            kept[last[0]] = last[1]
        timer.seconds.frontend = slam.frontend_seconds
        if slam.stereo is not None:  # computed inside SLAM calls (booked as tracking): a prior stage
            timer.seconds.tracking -= slam.stereo.seconds
            timer.seconds.priors += slam.stereo.seconds

        def summary():
            notes = [f"scene bound from {slam.bound.source}"] if slam.bound is not None else []
            if engine.depth_normal.auto_reason:
                notes.append(engine.depth_normal.auto_reason)
            if engine.depth_normal.description:
                fused = ""
                if fuses_stereo(cfg, engine.depth_normal.name) and slam.stereo is not None:
                    fused = ("; each keyframe's depth fitted to its plane-sweep stereo depth, which it fills "
                             f"(stereo.mono_fusion): {slam.stereo.fusion_note()}")
                notes.append(f"priors: {engine.depth_normal.description}{fused}")
            if slam.scale_rule:
                how = slam.init_note or "its shift from the normal prior"
                notes.append(f"metric scale: first frame's {slam.scale_from} taken as {cfg.loss.first_depth_median_m} m; "
                             f"shift {slam.scale_rule[1]:.4g}: {how}")
            if pacer.dropped:
                notes.append(f"--realtime dropped {pacer.dropped} frames (not in trajectory.tum)")
            if stop.requested:
                notes.append(f"stopped by {stop.reason} after {n} frames")
            track_pf, map_pf = timer.seconds.tracking / max(n, 1), timer.seconds.mapping / max(n, 1)
            def pct(xs):
                return [float(v) for v in np.percentile(xs, [50, 95])] if xs else [float("nan")] * 2
            lat = pct([x for x, _ in latency])
            steady = pct([x for x, ok in latency if ok])  # after the start-up (two-view hold, first mapping)
            return write_summary(
                out, frames=n, preset=cfg.preset, device=req.device, priors=provider_names(engine), timer=timer,
                interrupted=early, error=error, bound=slam.bound, source=req.source, notes=notes,
                intrinsics=intrinsics_dict(intr) if intr is not None else None,
                config=config_mod.to_dict(cfg),
                stats={"keyframes": len(slam.keyframes), "lost_frames": slam.lost_frames, "dropped_frames": pacer.dropped,
                       "tracking_s_per_frame": track_pf, "mapping_s_per_frame": map_pf,
                       "mapping_iterations": slam.mapped_iters, "runtime": runtime,
                       "mapped_frames": sorted(slam.mapped_frames),
                       "frame_indices": list(slam.order), "keyframe_indices": list(slam.keyframes),
                       "map_versions": slam.map_version, "mapping_wait_s": slam.mapping_wait_s,
                       "tracking_health": slam.health_summary(),
                       "sink_worker_s": sink.seconds if isinstance(sink, SinkWorker) else None,
                       "live_updates_skipped": live.skipped if live is not None else 0,
                       "pose_latency_median_s": lat[0], "pose_latency_p95_s": lat[1],
                       "pose_latency_after_startup_median_s": steady[0], "pose_latency_after_startup_p95_s": steady[1],
                       "skipped_corrupt_source_frames": getattr(source, "skipped_frames", 0)},
            )

        # Cheapest and most valuable first: a stop during the renders or the mesh keeps these.
        times, poses = slam.trajectory()
        write_trajectory(out, times, poses)
        if slam.model is not None:
            save_scene(out, cfg, slam.model, slam.beta)
        summary()
        mapped = slam.mapped_iters > 0  # otherwise the scene is the initial sphere: no renders, no mesh
        n_renders = sum(v is not None for v in kept.values()) if mapped and not early else 0
        print(f"writing outputs: {n_renders} renders{' and the mesh' if mapped else ''}", flush=True)
        with timer.stage("sinks"):
            poses_np = np.stack(poses) if poses else np.zeros((0, 4, 4))
            done_renders = 0
            order = list(zip(slam.order, times, poses))
            if sink is not None and order:  # the last frame's render is also the sink's view of the final
                order.insert(0, order.pop())  # map (the closing update had no live render): a stop keeps it
            for i, t, T in order:
                if n_renders and kept.get(i) is not None and not stop.requested:
                    done_renders += 1  # seconds each at full size: a line for each
                    say(f"writing outputs: render {done_renders}/{n_renders} (frame {i})")
                    view = render_image(slam.model, slam.beta, torch.as_tensor(T, dtype=torch.float32), intr, cfg.render)
                    save_render(out, i, view, kept[i], t)
                    if sink is not None and i == slam.order[-1]:
                        sink.log_map_render(i, view.rgb, view.depth, view.normal, intr, np.asarray(T, dtype=np.float64))
            mesh = None
            if mapped and len(poses):
                say(f"writing outputs: the mesh ({cfg.mesh.resolution}^3 grid)")
                try:
                    mesh = scene_mesh(slam.model, slam.beta, poses_np, intr, cfg, should_stop=lambda: stop.requested,
                                      measured=slam.measured_views(intr))
                except MeshAborted:  # a stop during the full mesh: a coarse one in a second or two
                    print(f"mesh extraction stopped: writing a coarse mesh ({MESH_RESOLUTION}^3) instead", flush=True)
                    mesh = coarse_mesh(slam, poses_np, intr)
            write_mesh(out, mesh)
            if sink is not None:
                if len(poses):
                    sink.log_trajectory(poses_np[:, :3, 3], rotations=poses_np[:, :3, :3])
                if mesh is not None and len(mesh.faces):
                    sink.log_mesh(np.asarray(mesh.vertices), np.asarray(mesh.faces), np.asarray(mesh.visual.vertex_colors)[:, :3])
                if mapped:
                    centres, betas = slam.beta.voxel_betas()
                    world = slam.model.bound.denormalise(centres.to(torch.float32)).cpu().numpy()
                    sink.log_beta_voxels(world, betas.cpu().numpy(), 2 * slam.model.bound.half_extent / slam.cfg.render.beta_voxels)
    finally:
        if isinstance(reader, ReadAhead):
            reader.close()
        if worker is not None:
            worker.close()
        if sink is not None:
            try:
                sink.close()
            except Exception as e:  # a sink failed (already logged): the files are written
                error = error or _report_error(e)
    early = early or stop.requested  # a stop during the renders or the mesh
    s = summary()
    print(f"{n} frames in {s.wall_s:.0f} s ({s.seconds_per_frame:.1f} s/frame: tracking "
          f"{s.stats['tracking_s_per_frame']:.1f}, mapping {s.stats['mapping_s_per_frame']:.1f}; "
          f"pose latency median / p95 {s.stats['pose_latency_median_s']:.1f} / {s.stats['pose_latency_p95_s']:.1f} s, "
          f"after the start-up {s.stats['pose_latency_after_startup_median_s']:.1f} / "
          f"{s.stats['pose_latency_after_startup_p95_s']:.1f} s; {runtime}); "
          f"{len(slam.lost_frames)} lost; outputs in {out}", flush=True)
    code = stop.exit_code if stop.requested else (1 if error is not None else 0)
    return RunOutcome(out, code, error)
