"""SIGINT / SIGTERM sent to a `nicer-stream run` process at three moments: each leaves a
trajectory that reads back, a summary with `interrupted: true`, closed Rerun and MCAP files,
and the conventional exit code."""
from __future__ import annotations

import json
import queue
import re
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from mcap.reader import make_reader

from nicer_stream.io import output_dir as od
from nicer_stream.io.trajectory import read_tum

# Each moment: how the tiny run is stretched so that it lasts (a line of the tiny config
# replaced), and the output line that says the moment has come.
MOMENTS = {
    "first_mapping": (("first_iters = 5", "first_iters = 100000"), r"first mapping"),
    "mid_sequence": (None, r"^frame\s+14\s+track loss"),
    "mesh_extraction": (("resolution = 24", "resolution = 400"), r"^writing outputs: the mesh"),
}


def _launch(tmp_path: Path, tiny_toml: str, change, frames: int, mapping_worker: str = "auto"):
    cfg = tmp_path / "cfg.toml"
    assert change is None or change[0] in tiny_toml
    cfg.write_text(tiny_toml.replace(*change) if change else tiny_toml)
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "nicer_stream.cli.main", "run", "--source", f"synthetic:room?frames={frames}",
           "--priors", "oracle:clean", "--config", str(cfg), "--out", str(out),
           "--sink", f"rerun:{tmp_path / 'rec.rrd'}", "--sink", f"mcap:{tmp_path / 'rec.mcap'}",
           "--mapping-worker", mapping_worker]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, bufsize=1)
    lines: queue.Queue[str] = queue.Queue()
    threading.Thread(target=lambda: [lines.put(line) for line in proc.stdout], daemon=True).start()
    return proc, lines, out


def _wait_for(proc, lines, pattern: str, timeout_s: float = 120.0) -> list[str]:
    seen, t0 = [], time.monotonic()
    while time.monotonic() - t0 < timeout_s:
        try:
            line = lines.get(timeout=0.5)
        except queue.Empty:
            assert proc.poll() is None, "the run ended before the moment came:\n" + "".join(seen)
            continue
        seen.append(line)
        if re.search(pattern, line, re.M):
            return seen
    proc.kill()
    raise AssertionError(f"no line matching {pattern!r} within {timeout_s} s:\n" + "".join(seen))


@pytest.mark.parametrize("moment,sig", [("first_mapping", signal.SIGINT), ("mid_sequence", signal.SIGTERM),
                                        ("mesh_extraction", signal.SIGINT)])
def test_a_stop_writes_what_was_computed_and_closes_the_recordings(tmp_path, tiny_toml, moment, sig):
    extra, pattern = MOMENTS[moment]
    # Mid-sequence with mapping on its worker thread: the call in hand stops too.
    proc, lines, out = _launch(tmp_path, tiny_toml, extra, frames=40, mapping_worker="on" if moment == "mid_sequence" else "auto")
    _wait_for(proc, lines, pattern)
    time.sleep(0.3)
    t_sig = time.monotonic()
    proc.send_signal(sig)
    code = proc.wait(timeout=60)
    stop_s = time.monotonic() - t_sig
    rest = []
    while not lines.empty():
        rest.append(lines.get())
    assert code == 128 + sig, "".join(rest)
    assert stop_s < 30, f"the stop took {stop_s:.0f} s"
    summary = json.loads((out / od.SUMMARY_FILE).read_text())
    assert summary["interrupted"] is True and summary["error"] is None
    t, poses = read_tum(out / od.TRAJECTORY_FILE)
    assert len(t) >= {"first_mapping": 1, "mid_sequence": 15, "mesh_extraction": 40}[moment]
    if moment == "mesh_extraction":  # the trajectory was complete; the mesh is the coarse one
        assert len(t) == 40
        assert any("writing a coarse mesh" in line for line in rest)
        assert (out / od.MESH_FILE).is_file()
    # The recordings were closed: MCAP has its footer (summary section), Rerun's file verifies.
    with open(tmp_path / "rec.mcap", "rb") as f:
        reader = make_reader(f)
        assert reader.get_summary() is not None
        n_msgs = sum(1 for _ in reader.iter_messages())
    assert n_msgs > 0
    rerun = Path(sys.executable).with_name("rerun")
    res = subprocess.run([str(rerun), "rrd", "verify", str(tmp_path / "rec.rrd")], capture_output=True, text=True)
    assert res.returncode == 0, res.stdout + res.stderr


_TWICE = """
import os, signal, sys, time
from nicer_stream.runtime.stop import StopSignals
with StopSignals() as stop:
    os.kill(os.getpid(), signal.SIGTERM)
    print("first:", stop.requested, stop.exit_code, flush=True)
    os.kill(os.getpid(), signal.SIGTERM)
    time.sleep(10)
    print("not reached", flush=True)
"""


def test_the_first_signal_asks_the_second_one_exits_at_once():
    t = time.monotonic()
    res = subprocess.run([sys.executable, "-c", _TWICE], capture_output=True, text=True, timeout=30)
    assert res.returncode == 143 and time.monotonic() - t < 8
    assert res.stdout == "first: True 143\n"  # the first one only set the flag
    assert "SIGTERM: stopping" in res.stderr
