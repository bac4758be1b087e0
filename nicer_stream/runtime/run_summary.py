"""summary.json of a `run`: the notes (bound, priors, scale, stops) and the run's statistics."""
from __future__ import annotations

from dataclasses import asdict

from nicer_stream.io import output_dir as od
from nicer_stream.runtime.frame_priors import fuses_stereo, provider_names
from nicer_stream.runtime.run_outputs import write_summary
from nicer_stream.runtime.run_state import RunState
from nicer_stream.runtime.sink_worker import SinkWorker


def run_notes(s: RunState) -> list[str]:
    """What a reader of summary.json should know about how the run went, one sentence each."""
    slam, dn = s.slam, s.engine.depth_normal
    notes = [f"scene bound from {slam.bound.source}"] if slam.bound is not None else []
    if dn.auto_reason:
        notes.append(dn.auto_reason)
    if dn.description:
        fused = ""
        if fuses_stereo(s.cfg, dn.name) and slam.stereo is not None:
            fused = ("; each keyframe's depth fitted to its plane-sweep stereo depth, which it fills "
                     f"(stereo.mono_fusion): {slam.stereo.fusion_note()}")
        notes.append(f"priors: {dn.description}{fused}")
    if slam.scale_rule:
        how = slam.init_note or "its shift from the normal prior"
        notes.append(f"metric scale: first frame's {slam.scale_from} taken as {s.cfg.loss.first_depth_median_m} m; "
                     f"shift {slam.scale_rule[1]:.4g}: {how}")
    if s.pacer.dropped:
        notes.append(f"--realtime dropped {s.pacer.dropped} frames (not in trajectory.tum)")
    if s.stop.requested:
        notes.append(f"stopped by {s.stop.reason} after {s.book.fed} frames")
    return notes


def run_stats(s: RunState) -> dict:
    """summary.json's `stats` of a run."""
    slam, n = s.slam, s.book.fed
    lat, steady = s.book.latency_percentiles()
    return {"keyframes": len(slam.keyframes), "lost_frames": slam.lost_frames, "dropped_frames": s.pacer.dropped,
            "tracking_s_per_frame": s.timer.seconds.tracking / max(n, 1),
            "mapping_s_per_frame": s.timer.seconds.mapping / max(n, 1),
            "mapping_iterations": slam.mapped_iters, "runtime": s.threads.description,
            "mapped_frames": sorted(slam.mapped_frames),
            "frame_indices": list(slam.order), "keyframe_indices": list(slam.keyframes),
            "map_versions": slam.map_version, "mapping_wait_s": slam.mapping_wait_s,
            "tracking_health": slam.health_summary(),
            "sink_worker_s": s.sink.seconds if isinstance(s.sink, SinkWorker) else None,
            "live_updates_skipped": s.live.skipped if s.live is not None else 0,
            "pose_latency_median_s": lat[0], "pose_latency_p95_s": lat[1],
            "pose_latency_after_startup_median_s": steady[0], "pose_latency_after_startup_p95_s": steady[1],
            "skipped_corrupt_source_frames": getattr(s.source, "skipped_frames", 0)}


def write_run_summary(s: RunState) -> od.Summary:
    """Write summary.json as the run stands now (written again after the renders and the mesh)."""
    intr = s.book.intr
    return write_summary(
        s.out, frames=s.book.fed, preset=s.cfg.preset, device=s.req.device, priors=provider_names(s.engine),
        timer=s.timer, interrupted=s.early, error=s.error, bound=s.slam.bound, source=s.req.source,
        notes=run_notes(s), intrinsics=asdict(intr) if intr is not None else None,
        config=asdict(s.cfg), stats=run_stats(s))


def final_line(s: RunState, summary: od.Summary) -> str:
    """The run's last console line: frames, seconds per stage, pose latency, lost frames, outputs."""
    st = summary.stats
    return (f"{s.book.fed} frames in {summary.wall_s:.0f} s ({summary.seconds_per_frame:.1f} s/frame: tracking "
            f"{st['tracking_s_per_frame']:.1f}, mapping {st['mapping_s_per_frame']:.1f}; "
            f"pose latency median / p95 {st['pose_latency_median_s']:.1f} / {st['pose_latency_p95_s']:.1f} s, "
            f"after the start-up {st['pose_latency_after_startup_median_s']:.1f} / "
            f"{st['pose_latency_after_startup_p95_s']:.1f} s; {s.threads.description}); "
            f"{len(s.slam.lost_frames)} lost; outputs in {s.out}")
