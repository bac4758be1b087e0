"""A run with a sink keeps every core mapping: the sink worker's own thread count once made the
SLAM thread take a single thread from its second mapping call on (the demo ran 2x slower).
A subprocess: the thread counts are process state that pytest's other tests already set."""
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[3]

SPY = r'''
import os, sys, time
import torch

def busy_threads(seconds=0.5):
    """Threads of this process that used over a third of `seconds` of CPU in a parallel torch loop."""
    def cpu():
        out = {}
        for t in os.listdir("/proc/self/task"):
            try:
                f = open(f"/proc/self/task/{t}/stat").read().rsplit(")", 1)[1].split()
            except FileNotFoundError:
                continue
            out[t] = int(f[11]) + int(f[12])
        return out
    before, x, t0 = cpu(), torch.randn(4_000_000), time.perf_counter()
    while time.perf_counter() - t0 < seconds:
        x.exp().sum()
    after, hz = cpu(), os.sysconf("SC_CLK_TCK")
    return sum((after[t] - before.get(t, 0)) / hz > seconds / 3 for t in after)

import nicer_stream.mapping.mapper as mapper
optimise = mapper.Mapper.optimise
def spy(self, *a, **k):
    print("BUSY", busy_threads(), flush=True)
    return optimise(self, *a, **k)
mapper.Mapper.optimise = spy
from nicer_stream.cli.main import app
app(sys.argv[1:])
'''


@pytest.mark.skipif(not Path("/proc/self/task").exists() or len(os.sched_getaffinity(0)) < 2,
                    reason="needs Linux /proc and two cores")
def test_a_sink_leaves_mapping_all_cores(tmp_path):
    cfg = tmp_path / "cheap.toml"
    cfg.write_text("max_side = 96\n[mapping]\niters = 2\nfirst_iters = 3\nfinal_iters = 2\nbatch_iters = 3\n"
                   "[tracking]\niters = 2\n")
    out = tmp_path / "out"
    env = {**os.environ, "PYTHONPATH": str(ROOT), "OMP_NUM_THREADS": "2"}
    r = subprocess.run([sys.executable, "-c", SPY, "run", "--source", "synthetic:room?frames=8", "--out", str(out),
                        "--priors", "oracle:clean", "--config", str(cfg), "--sink", f"mcap:{out}/run.mcap", "--quiet"],
                       capture_output=True, text=True, env=env, timeout=300, cwd=ROOT)
    assert r.returncode == 0, r.stderr[-2000:]
    busy = [int(line.split()[1]) for line in r.stdout.splitlines() if line.startswith("BUSY")]
    assert len(busy) >= 2, r.stdout[-2000:]
    assert all(b == 2 for b in busy), busy
