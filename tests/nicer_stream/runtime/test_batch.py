"""`nicer-stream batch`: sources expanded and named, complete outputs skipped, a bad source
recorded while the others go on (on a local Ray instance and with --local), and a killed
worker retried."""
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from nicer_stream.errors import UserError
from nicer_stream.io import output_dir as od
from nicer_stream.runtime.batch_plan import PID_FILE, RunOptions, expand_sources, plan, per_source_sinks
from nicer_stream.runtime.slam_run import RunRequest
from nicer_stream.runtime.batch_run import BatchRequest, run_batch

SOURCES = ["synthetic:room?frames=4", "synthetic:tabletop?frames=4", "synthetic:room?frames=5"]


def test_sources_from_globs_and_lists_get_distinct_names(tmp_path):
    for n in ("b", "a"):
        (tmp_path / f"{n}.mcap").write_bytes(b"")
    lst = tmp_path / "list.txt"
    lst.write_text(f"# logs\nmcap:{tmp_path}/*.mcap?topic=/cam\nsynthetic:room?frames=4\n")
    got = expand_sources([str(lst), "folder:/data/run/"])
    assert got == [f"mcap:{tmp_path}/a.mcap?topic=/cam", f"mcap:{tmp_path}/b.mcap?topic=/cam",
                   "synthetic:room?frames=4", "folder:/data/run/"]
    names = [i.name for i in plan(got + ["folder:/other/run"])]
    assert names == ["a", "b", "room_frames_4", "run", "run_2"]
    with pytest.raises(UserError, match="no file matches"):
        expand_sources([f"mcap:{tmp_path}/*.bag"])


def _check(rep, root: Path, bad: str):
    by = {r.name: r for r in rep.sources}
    good = [i.name for i in plan(SOURCES)]
    for name in good:
        assert by[name].status in ("done", "skipped"), by[name]
        assert (root / name / od.TRAJECTORY_FILE).is_file() and by[name].frames in (4, 5)
        assert by[name].ate_cm is not None  # synthetic sources have GT: evaluated
    assert by[bad].status == "failed" and by[bad].error and "\n" not in by[bad].error
    on_disk = json.loads((root / "batch.json").read_text())
    assert [(r["name"], r["status"]) for r in on_disk["sources"]] == [(r.name, r.status) for r in rep.sources]


@pytest.mark.parametrize("local", [False, True], ids=["ray", "local"])
def test_batch_runs_every_source_reports_the_bad_one_and_skips_complete_ones(tmp_path, tiny_config, local):
    if not local:
        pytest.importorskip("ray")
    bad = tmp_path / "bad.mcap"
    bad.write_bytes(b"\x89MCAP0\r\nthis is not an mcap file")
    items = tuple(plan(SOURCES + [f"mcap:{bad}"]))
    req = BatchRequest(items, tmp_path / "root", RunOptions(RunRequest(source="", out_dir=Path(), config_file=str(tiny_config), priors="oracle:clean")),
                       local=local, quiet=True)
    try:
        rep = run_batch(req)
        _check(rep, tmp_path / "root", "bad")
        assert all(r.status == "done" for r in rep.sources if r.name != "bad")
        again = run_batch(req)  # complete outputs are skipped; the bad source is tried again
        _check(again, tmp_path / "root", "bad")
        assert all(r.status == "skipped" for r in again.sources if r.name != "bad")
    finally:
        if not local:
            import ray

            ray.shutdown()


def _batch_until_a_worker_runs(root: Path, sources: list[str], first: str, config, *extra):
    """Start `nicer-stream batch` in a process; return it once source `first`'s worker wrote its pid."""
    exe = Path(sys.executable).with_name("nicer-stream")
    proc = subprocess.Popen([str(exe), "batch", *sources, "--out", str(root), "--config", str(config),
                             "--priors", "oracle:clean", "--no-eval", *extra],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    pid_file = root / first / PID_FILE
    deadline = time.time() + 120
    while not pid_file.is_file() and time.time() < deadline and proc.poll() is None:
        time.sleep(0.2)
    assert pid_file.is_file(), proc.communicate()[0]
    return proc, int(pid_file.read_text())


def test_a_killed_worker_is_retried_and_the_source_completes(tmp_path, tiny_config):
    pytest.importorskip("ray")
    root = tmp_path / "root"
    proc, pid = _batch_until_a_worker_runs(root, ["synthetic:room?frames=12"], "room_frames_12", tiny_config,
                                           "--retries", "1")
    time.sleep(2.0)  # mid-run
    os.kill(pid, signal.SIGKILL)
    out = proc.communicate(timeout=300)[0]
    assert proc.returncode == 0, out
    rec = json.loads((root / "batch.json").read_text())["sources"][0]
    assert rec["status"] == "done" and rec["attempts"] == 2, rec
    assert od.read_summary(root / "room_frames_12").frames == 12


def test_ctrl_c_stops_scheduling_keeps_partial_outputs_and_writes_batch_json(tmp_path, tiny_config):
    pytest.importorskip("ray")
    root = tmp_path / "root"
    sources = [f"synthetic:room?frames={n}" for n in (80, 81, 82)]
    proc, _ = _batch_until_a_worker_runs(root, sources, "room_frames_80", tiny_config)
    time.sleep(3.0)
    proc.send_signal(signal.SIGINT)
    out = proc.communicate(timeout=180)[0]
    assert proc.returncode == 130, out
    rep = json.loads((root / "batch.json").read_text())
    assert rep["interrupted"] is True
    statuses = {r["name"]: r["status"] for r in rep["sources"]}
    assert statuses["room_frames_80"] == "interrupted", out
    assert set(statuses.values()) <= {"interrupted", "cancelled", "pending", "done"}
    assert od.read_summary(root / "room_frames_80").interrupted  # the run wrote its partial outputs
    assert (root / "room_frames_80" / od.TRAJECTORY_FILE).is_file()
