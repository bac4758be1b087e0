"""`nicer-stream batch`: every source as one Ray task (a local instance by default, a cluster
with `address`), or the same plan sequentially in this process (`local`). Outputs go to
ROOT/<name>/ (the usual output contract); ROOT/batch.json is rewritten after each source.

Faults: a source that fails is recorded with its one-line error and the others go on (no retry:
the same input fails the same way); a worker process that dies (killed, out of memory) is
retried `retries` times by Ray; a second invocation skips sources whose outputs are complete.
Ctrl-C stops scheduling, asks running tasks to stop (each writes its partial outputs, as a
stopped `run` does) and writes batch.json.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, replace
from pathlib import Path

from nicer_stream.errors import UserError, one_line
from nicer_stream.runtime.batch_plan import (BatchItem, BatchProgress, BatchReport, RunOptions, SourceRecord,
                                             is_complete, record_from_outputs, run_one, write_report)
from nicer_stream.runtime.stop import StopSignals

RAY_HINT = "Ray is not installed: pip install 'nicer-stream[ray]' (or run the same plan sequentially with --local)"


@dataclass(frozen=True)
class BatchRequest:
    items: tuple[BatchItem, ...]
    root: Path
    opts: RunOptions = RunOptions()
    local: bool = False
    """Sequentially in this process, without Ray."""
    address: str | None = None
    """None: a local Ray instance sized to this machine; 'auto' or ray://HOST:PORT: a cluster."""
    cpus_per_run: float = 1.0
    gpus_per_run: float = 0.0
    retries: int = 1
    force: bool = False
    """Redo sources whose outputs are complete."""
    quiet: bool = False


def run_batch(req: BatchRequest) -> BatchReport:
    root = Path(req.root)
    root.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    report = BatchReport(str(root), scheduler="local (sequential)" if req.local else f"ray ({req.address or 'local instance'})")
    records: dict[str, SourceRecord] = {}
    todo = []
    for item in req.items:
        if not req.force and is_complete(root / item.name):
            records[item.name] = record_from_outputs(item, root / item.name, "skipped")
        else:
            records[item.name] = SourceRecord(item.name, item.source, "pending")
            todo.append(item)
    run = req.opts.request
    opts = replace(req.opts, request=replace(run, device="cuda" if req.gpus_per_run > 0 else run.device))
    progress = BatchProgress(len(todo), req.quiet)
    if not req.quiet:
        skipped = len(req.items) - len(todo)
        print(f"{len(req.items)} sources ({skipped} complete, skipped; --force redoes them); "
              f"{len(todo)} to run with {report.scheduler}", flush=True)

    def finished(rec: SourceRecord) -> None:
        records[rec.name] = rec
        progress.finished(rec)
        report.sources = [records[i.name] for i in req.items]
        report.wall_s = time.perf_counter() - t0
        write_report(report)

    with StopSignals() as stop:
        if todo:
            (_run_local if req.local else _run_ray)(req, todo, opts, finished, lambda: stop.requested)
        report.interrupted = stop.requested
    report.sources = [records[i.name] for i in req.items]
    report.wall_s = time.perf_counter() - t0
    write_report(report)
    return report


def _run_local(req: BatchRequest, todo: list[BatchItem], opts: RunOptions, finished, stopping) -> None:
    for item in todo:
        if stopping():
            break
        rec = run_one(item, str(req.root), opts)
        rec.attempts = 1
        finished(rec)


def _run_ray(req: BatchRequest, todo: list[BatchItem], opts: RunOptions, finished, stopping) -> None:
    try:
        import ray
    except ImportError:
        raise UserError(RAY_HINT) from None
    if not ray.is_initialized():
        if req.address:
            ray.init(address=req.address, log_to_driver=False)
        else:  # a local instance sized to this machine
            ray.init(include_dashboard=False, log_to_driver=False)
    task = ray.remote(num_cpus=req.cpus_per_run, num_gpus=req.gpus_per_run, max_retries=req.retries,
                      retry_exceptions=False)(_task)
    refs = {task.remote(item, str(req.root), opts, req.cpus_per_run): item for item in todo}
    cancelled = False
    while refs:
        if stopping() and not cancelled:  # stop scheduling; running tasks write their partial outputs
            for ref in refs:
                ray.cancel(ref, force=False)
            cancelled = True
        ready, _ = ray.wait(list(refs), num_returns=1, timeout=0.5)
        for ref in ready:
            item = refs.pop(ref)
            try:
                rec = ray.get(ref)
            except (ray.exceptions.TaskCancelledError, ray.exceptions.RayTaskError) as e:
                out = Path(req.root) / item.name
                status = ("interrupted" if (out / "summary.json").is_file() else "cancelled") if cancelled else "failed"
                rec = record_from_outputs(item, out, status, None if cancelled else one_line(e)[:300])
            except ray.exceptions.WorkerCrashedError as e:  # retried `retries` times already
                rec = record_from_outputs(item, Path(req.root) / item.name, "failed",
                                          f"the worker died {req.retries + 1} times: {one_line(e)[:300]}")
            finished(rec)


def _task(item: BatchItem, root: str, opts: RunOptions, cpus: float) -> SourceRecord:
    """One source inside a Ray worker: torch gets the task's CPUs."""
    import torch

    torch.set_num_threads(max(1, int(cpus)))
    attempts_file = Path(root) / item.name / ".attempts"
    attempts_file.parent.mkdir(parents=True, exist_ok=True)
    n = int(attempts_file.read_text()) + 1 if attempts_file.is_file() else 1
    attempts_file.write_text(str(n))
    rec = run_one(item, root, opts)
    rec.attempts = n
    attempts_file.unlink(missing_ok=True)
    return rec
