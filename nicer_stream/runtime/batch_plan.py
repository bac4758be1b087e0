"""`nicer-stream batch`: which sources, where each one's outputs go, which are already done, and
one source's run as a plain function (what a Ray task or the sequential `--local` loop calls).
The scheduling itself is in runtime/batch_ray.py and runtime/batch_local.py."""
from __future__ import annotations

import glob
import json
import os
import re
import time
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

from nicer_stream.errors import UserError, one_line
from nicer_stream.io import output_dir as od
from nicer_stream.runtime.slam_run import RunRequest, run_slam

BATCH_FILE = "batch.json"
PID_FILE = ".worker.pid"  # the process running a source (for tests and for users who need to kill one)


@dataclass(frozen=True)
class BatchItem:
    """One source of the batch and its output directory ROOT/name."""

    source: str
    name: str


@dataclass
class SourceRecord:
    """A row of batch.json and of the printed table."""

    name: str
    source: str
    status: str
    """'done', 'failed', 'interrupted' (stopped, partial outputs written), 'cancelled' (stopped
    before it started), 'skipped' (outputs already complete) or 'pending'."""
    frames: int | None = None
    s_per_frame: float | None = None
    ate_cm: float | None = None
    mesh_acc_cm: float | None = None
    mesh_comp_cm: float | None = None
    error: str | None = None
    attempts: int = 0


@dataclass
class BatchReport:
    root: str
    sources: list[SourceRecord] = field(default_factory=list)
    wall_s: float = 0.0
    scheduler: str = ""
    interrupted: bool = False


def expand_sources(args: list[str]) -> list[str]:
    """Source URIs from URIs, globs in a URI's path (`mcap:logs/*.mcap`, `*` and `[...]`; a
    query after `?` is kept for every match) and text files of URIs (one per line, `#`
    comments), in the order given."""
    out: list[str] = []
    for a in args:
        path = Path(a)
        if ":" not in a and path.suffix == ".txt":
            if not path.is_file():
                raise UserError(f"source list {a} not found: give URIs, globs or a text file of URIs")
            lines = [ln.split("#", 1)[0].strip() for ln in path.read_text().splitlines()]
            out += expand_sources([ln for ln in lines if ln])
            continue
        scheme, sep, rest = a.partition(":")
        pattern, q, query = rest.partition("?")  # '?' starts the URI's query: globs use * and [...]
        if sep and any(c in pattern for c in "*["):
            matches = sorted(glob.glob(pattern))
            if not matches:
                raise UserError(f"no file matches {a}: check the pattern")
            out += [f"{scheme}:{m}{q}{query}" for m in matches]
        else:
            out.append(a)
    if not out:
        raise UserError("no sources given: pass URIs, globs (mcap:logs/*.mcap) or a text file of URIs")
    return out


def plan(sources: list[str]) -> list[BatchItem]:
    """A distinct output name per source: its file or folder name (the synthetic scene's name and
    query for `synthetic:`), made unique with a suffix."""
    items, used = [], set()
    for s in sources:
        scheme, _, rest = s.partition(":")
        base = Path(rest.split("?", 1)[0].rstrip("/")).stem or scheme
        if scheme == "synthetic":
            base = re.sub(r"[^A-Za-z0-9]+", "_", rest).strip("_")
        base = re.sub(r"[^A-Za-z0-9._-]+", "_", base) or "source"
        name, k = base, 2
        while name in used:
            name, k = f"{base}_{k}", k + 1
        used.add(name)
        items.append(BatchItem(s, name))
    return items


def is_complete(out_dir: Path) -> bool:
    """The run finished: summary.json without interruption or error, and its trajectory."""
    try:
        s = od.read_summary(out_dir)
    except UserError:
        return False
    return not s.interrupted and s.error is None and (out_dir / od.TRAJECTORY_FILE).is_file()


def record_from_outputs(item: BatchItem, out_dir: Path, status: str, error: str | None = None) -> SourceRecord:
    """The table row of a source from what its directory holds."""
    rec = SourceRecord(item.name, item.source, status, error=error)
    try:
        s = od.read_summary(out_dir)
        rec.frames, rec.s_per_frame = s.frames, s.seconds_per_frame
        rec.error = rec.error or s.error
    except UserError:
        return rec
    if (out_dir / od.EVAL_FILE).is_file():
        e = od.read_eval(out_dir)
        cm = (lambda x: None if x is None else 100 * x)
        rec.ate_cm, rec.mesh_acc_cm, rec.mesh_comp_cm = cm(e.ate_rmse_m), cm(e.mesh.acc_m), cm(e.mesh.comp_m)
    return rec


@dataclass(frozen=True)
class RunOptions:
    """What every source of the batch gets."""

    request: RunRequest = field(default_factory=lambda: RunRequest(source="", out_dir=Path()))
    """The `run` request of each source, its source and output directory replaced (and quiet)."""
    evaluate: bool = True
    """Evaluate each output directory against the source's ground truth, where it has some."""


def per_source_sinks(specs: tuple[str, ...], out: Path) -> tuple[str, ...]:
    """Sink specs with each file moved into the source's own directory (`mcap:rec.mcap` ->
    `mcap:ROOT/NAME/rec.mcap`), so that the sources do not write one file."""
    res = []
    for spec in specs:
        parts = []
        for part in spec.split(","):
            base, q, query = part.partition("?")
            kind, sep, path = base.partition(":")
            if kind in ("rerun", "mcap") and path:
                base = f"{kind}:{out / Path(path).name}"
            parts.append(base + q + query)
        res.append(",".join(parts))
    return tuple(res)


def run_one(item: BatchItem, root: str, opts: RunOptions) -> SourceRecord:
    """Run SLAM on one source into ROOT/name (quiet), evaluate it when it has ground truth, and
    return its row. Errors become the row's one-line error, never an exception."""
    out = Path(root) / item.name
    out.mkdir(parents=True, exist_ok=True)
    (out / PID_FILE).write_text(str(os.getpid()))
    req = replace(opts.request, source=item.source, out_dir=out, quiet=True,
                  sinks=per_source_sinks(opts.request.sinks, out))
    src_opts = req.source_opts
    try:
        res = run_slam(req)
        if res.exit_code in (130, 143):
            return record_from_outputs(item, out, "interrupted")
        if res.exit_code:
            return record_from_outputs(item, out, "failed", res.error)
        if opts.evaluate:
            _evaluate(item, out, src_opts)
        return record_from_outputs(item, out, "done")
    except KeyboardInterrupt:
        return record_from_outputs(item, out, "interrupted")
    except Exception as e:  # UserError (bad file, no camera topic, ...) or a bug: one line
        return record_from_outputs(item, out, "failed", one_line(e))
    finally:
        (out / PID_FILE).unlink(missing_ok=True)


def _evaluate(item: BatchItem, out: Path, src_opts) -> None:
    from nicer_stream.eval.evaluate import evaluate_output_dir
    from sources import open_source

    src = open_source(item.source, src_opts)
    if src.has_gt_pose:
        od.write_eval(out, evaluate_output_dir(out, src))


def write_report(report: BatchReport) -> Path:
    """ROOT/batch.json, atomically (rewritten after every finished source)."""
    path = Path(report.root) / BATCH_FILE
    tmp = path.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(asdict(report), indent=2) + "\n")
    tmp.replace(path)
    return path


def table(records: list[SourceRecord]) -> str:
    """The printed summary: one row per source."""
    def f(x, fmt):
        return "-" if x is None else format(x, fmt)

    rows = ["| source | status | frames | s/frame | ATE cm | mesh acc / comp cm | error |", "|---|---|---|---|---|---|---|"]
    for r in records:
        rows.append(f"| {r.name} | {r.status} | {f(r.frames, 'd')} | {f(r.s_per_frame, '.1f')} | {f(r.ate_cm, '.2f')} | "
                    f"{f(r.mesh_acc_cm, '.2f')} / {f(r.mesh_comp_cm, '.2f')} | {r.error or ''} |")
    return "\n".join(rows)


class BatchProgress:
    """One line per finished source with the overall [done/total, failures, ETA]."""

    def __init__(self, total: int, quiet: bool = False) -> None:
        self.total, self.done, self.failed, self.quiet = total, 0, 0, quiet
        self.t0 = time.perf_counter()

    def finished(self, rec: SourceRecord) -> None:
        self.done += 1
        self.failed += rec.status == "failed"
        el = time.perf_counter() - self.t0
        eta = el / self.done * (self.total - self.done)
        if not self.quiet:
            extra = f": {rec.error}" if rec.error else ""
            print(f"{rec.name}: {rec.status}{extra}  [{self.done}/{self.total}, {self.failed} failed, eta {eta:.0f} s]",
                  flush=True)
