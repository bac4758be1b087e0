"""`nicer-stream inspect PATH_OR_URI`: describe a .rrd recording, an .mcap file, an output
directory (its summary and eval table) or a frame source; `--json` prints the same as JSON."""
from __future__ import annotations

import json
from collections import Counter, defaultdict
from dataclasses import asdict
from pathlib import Path

import typer

from nicer_stream.cli.common import user_errors
from nicer_stream.errors import UserError



def describe_rrd(path: Path) -> list[str]:
    """Recordings, then one line per entity path: row count, static or timelines, archetype columns."""
    from rerun.chunk import RrdReader

    try:
        reader = RrdReader(path)
        recs = reader.recordings()
        rows: Counter[str] = Counter()
        timelines: dict[str, set[str]] = defaultdict(set)
        columns: dict[str, set[str]] = defaultdict(set)
        for ch in reader.stream():
            rows[ch.entity_path] += ch.num_rows
            timelines[ch.entity_path].update(ch.timeline_names)
            names = ch.to_record_batch().schema.names
            columns[ch.entity_path].update(n.split(":")[0] for n in names if ":" in n)
    except (RuntimeError, ValueError, OSError) as e:
        raise UserError(f"cannot read {path} as a Rerun recording ({str(e).splitlines()[0]}): "
                        "is it a .rrd written by rerun-sdk 0.41?") from None
    lines = [f"Rerun recording {path}"]
    lines += [f"  recording app_id={r.application_id} recording_id={r.recording_id}" for r in recs]
    lines.append(f"{len(rows)} entities:")
    width = max((len(e) for e in rows), default=0)
    for entity in sorted(rows):
        when = ",".join(sorted(timelines[entity])) or "static"
        lines.append(f"  {entity:<{width}}  rows={rows[entity]:<5} [{when}]  {' '.join(sorted(columns[entity]))}")
    return lines


def _ns_text(ns: int) -> str:
    """Integer ns -> exact seconds text (a float would lose the last digits of epoch times)."""
    return f"{ns // 10**9}.{ns % 10**9:09d}"


def _scan_mcap(f) -> tuple[dict, dict, Counter, int | None, int | None, bool]:
    """Read every message header (for files without a summary). Returns channels, schemas,
    counts per channel id, first/last log time, and whether the file ended early."""
    from mcap.reader import NonSeekingReader

    channels, schemas, counts = {}, {}, Counter()
    t0 = t1 = None
    truncated = False
    try:
        for schema, channel, msg in NonSeekingReader(f).iter_messages(log_time_order=False):
            channels[channel.id] = channel
            if schema is not None:
                schemas[schema.id] = schema
            counts[channel.id] += 1
            t0 = msg.log_time if t0 is None else min(t0, msg.log_time)
            t1 = msg.log_time if t1 is None else max(t1, msg.log_time)
    except Exception:  # mcap raises EndOfFile and friends on a cut-off file: report what came before
        truncated = True
    return channels, schemas, counts, t0, t1, truncated


def describe_mcap(path: Path) -> list[str]:
    """Profile, time range, then one line per topic: schema, encoding, message count."""
    from mcap.reader import make_reader

    from sources.mcap_source import MAGIC

    with open(path, "rb") as f:
        if f.read(len(MAGIC)) != MAGIC:
            raise UserError(f"{path} is not an MCAP file (bad magic bytes): give a .mcap file")
        f.seek(0)
        summary, profile = None, "?"
        try:
            reader = make_reader(f)
            profile = reader.get_header().profile
            summary = reader.get_summary()
        except Exception:  # no summary or footer (cut-off file): fall back to a scan below
            pass
        if summary is not None and summary.statistics is not None:
            st = summary.statistics
            channels, schemas = summary.channels, summary.schemas
            counts = Counter(st.channel_message_counts)
            t0, t1, truncated = st.message_start_time, st.message_end_time, False
        else:
            f.seek(0)
            channels, schemas, counts, t0, t1, truncated = _scan_mcap(f)
    lines = [f"MCAP {path} (profile '{profile}')"]
    if truncated:
        lines.append("  warning: the file ends early (not finalised); counts cover what could be read")
    if t0 is not None and t1 is not None and sum(counts.values()):
        lines.append(f"time range: {_ns_text(t0)} .. {_ns_text(t1)} s ({(t1 - t0) / 1e9:.3f} s)")
    lines.append(f"{sum(counts.values())} messages on {len(channels)} topics:")
    width = max((len(c.topic) for c in channels.values()), default=0)
    for ch in sorted(channels.values(), key=lambda c: c.topic):
        schema = schemas.get(ch.schema_id)
        name = schema.name if schema is not None else "(no schema)"
        lines.append(f"  {ch.topic:<{width}}  {counts.get(ch.id, 0):>6} msgs  {name} [{ch.message_encoding}]")
    return lines


def describe_source(uri: str) -> list[str]:
    """Frame count if known, then the first frame's size, intrinsics and GT availability."""
    import sources

    try:
        src = sources.open_source(uri)
    except ModuleNotFoundError as e:
        raise UserError(f"source '{uri}' needs module {e.name}, which is not available in this install") from None
    try:
        count = str(len(src))
    except TypeError:
        count = "unknown until read"
    first = next(iter(src), None)
    lines = [f"source {uri} ({type(src).__name__})", f"frames: {count}"]
    if first is None:
        return lines + ["no frames could be read"]
    k = first.intrinsics
    lines.append(f"size: {first.width} x {first.height}")
    lines.append(f"intrinsics: fx={k.fx:.3f} fy={k.fy:.3f} cx={k.cx:.3f} cy={k.cy:.3f}")
    lens = getattr(src, "calibration", None)
    if lens is not None and lens.is_distorted:
        r = lens.intrinsics(first.width, first.height)
        lines.append(f"lens: {lens.model} distortion {[round(float(d), 6) for d in lens.distortion]} with recorded "
                     f"fx={r.fx:.3f} fy={r.fy:.3f} cx={r.cx:.3f} cy={r.cy:.3f}; frames undistorted to the intrinsics above")
    gt_pose = first.gt_pose is not None or bool(getattr(src, "has_gt_pose", False))
    lines.append(f"ground truth: pose {'yes' if gt_pose else 'no'}, depth {'yes' if first.gt_depth is not None else 'no'}")
    return lines


def describe_outputs(path: Path) -> tuple[list[str], dict]:
    """An output directory: what ran (summary.json), how it ended, and eval.json's table."""
    from nicer_stream.cli.eval_cmd import format_table
    from nicer_stream.io import output_dir as od

    s = od.read_summary(path)
    data: dict = {"kind": "outputs", "path": str(path), "summary": asdict(s), "eval": None,
                  "files": sorted(p.name for p in path.iterdir())}
    ended = "completed" if not s.interrupted else f"ended early{': ' + s.error if s.error else ''}"
    lines = [f"output directory {path} ({ended})",
             f"source {s.source}, preset {s.preset}, priors {', '.join(s.priors)}, device {s.device}",
             f"{s.frames} frames in {s.wall_s:.0f} s ({s.seconds_per_frame:.2f} s/frame; tracking "
             f"{s.stages_s.tracking:.0f} s, mapping {s.stages_s.mapping:.0f} s, priors {s.stages_s.priors:.0f} s, "
             f"sinks {s.stages_s.sinks:.0f} s), peak RSS {s.peak_rss_mb:.0f} MB"]
    lines += [f"  note: {n}" for n in s.notes]
    lines.append("files: " + " ".join(data["files"]))
    if (path / od.EVAL_FILE).is_file():
        rep = od.read_eval(path)
        data["eval"] = asdict(rep)
        lines += format_table(rep).splitlines()
    else:
        lines.append(f"no {od.EVAL_FILE} (run `nicer-stream eval {path}` against a source with ground truth)")
    return lines, data


def describe_with_data(target: str) -> tuple[list[str], dict]:
    """(text lines, the same as a JSON-ready dict) for `target`: a .rrd or .mcap file, an output
    directory or a source URI."""
    from nicer_stream.io.output_dir import SUMMARY_FILE

    path = Path(target)
    if path.is_dir() and (path / SUMMARY_FILE).is_file():
        return describe_outputs(path)
    lines = _describe_file_or_source(target, path)
    kind = path.suffix[1:] if path.suffix in (".rrd", ".mcap") and path.is_file() else "source"
    return lines, {"kind": kind, "target": target, "lines": lines}


def _describe_file_or_source(target: str, path: Path) -> list[str]:
    from sources import SCHEMES

    scheme = target.split(":", 1)[0] if ":" in target else None
    if path.suffix in (".rrd", ".mcap") and scheme not in SCHEMES:
        if not path.is_file():
            raise UserError(f"{target} not found: give an existing .rrd or .mcap file")
        return describe_rrd(path) if path.suffix == ".rrd" else describe_mcap(path)
    if scheme in SCHEMES or (scheme and not path.exists()):
        return describe_source(target)  # unknown schemes get the registry's one-line error
    if not path.exists():
        raise UserError(f"{target} not found: give a .rrd or .mcap file, or a source URI "
                        f"({', '.join(s + ':PATH' for s in SCHEMES)})")
    raise UserError(f"cannot inspect {target}: give a .rrd or .mcap file, an output directory (with "
                    f"summary.json) or a source URI ({', '.join(s + ':PATH' for s in SCHEMES)})")


@user_errors
def inspect_command(
    target: str = typer.Argument(..., help="A .rrd or .mcap file, an output directory, or a source URI such as replica:PATH."),
    as_json: bool = typer.Option(False, "--json", help="Print JSON (for scripts) instead of text."),
) -> None:
    """Describe a recording (.rrd entities, .mcap topics), an output directory (summary, eval table) or a source (frames, size, intrinsics, GT)."""
    lines, data = describe_with_data(target)
    if as_json:
        typer.echo(json.dumps(data, indent=2, default=str))
        return
    for line in lines:
        typer.echo(line)
