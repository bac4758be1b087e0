"""Memory over a long run (issue 15): `nicer-stream run` on a 1,000-frame synthetic room with a
cheap configuration; the process's RSS and peak RSS are read from /proc when the run prints
frames 250, 500 and 1,000. Prints a table; `--config-extra` adds TOML lines (e.g. to turn the
keyframe cap off with `[mapping]\\nfull_res_keyframes = 0`).

Usage: .venv/bin/python scripts/memory_bench.py --out runs/mem [--frames 1000] [--config-extra TEXT]
"""
from __future__ import annotations

import argparse
import re
import subprocess
import sys
import time
from pathlib import Path

CHEAP = """max_side = 160
[mapping]
iters = 5
first_iters = 20
final_iters = 5
rays = 256
eikonal_points = 32
{mapping_extra}
[tracking]
iters = 3
rays = 128
[mesh]
resolution = 64
"""


def vm_kb(pid: int) -> dict[str, int]:
    out = {}
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith(("VmRSS", "VmHWM")):
            key, val = line.split(":")
            out[key] = int(val.split()[0])
    return out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", required=True)
    ap.add_argument("--frames", type=int, default=1000)
    ap.add_argument("--mapping-extra", default="", help="extra lines for the [mapping] section")
    a = ap.parse_args()
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    cfg = out / "cheap.toml"
    cfg.write_text(CHEAP.format(mapping_extra=a.mapping_extra.replace("\\n", "\n")))
    marks = sorted({a.frames // 4, a.frames // 2, a.frames})
    cmd = [sys.executable, "-m", "nicer_stream.cli.main", "run", "--source", f"synthetic:room?frames={a.frames}",
           "--priors", "oracle:clean", "--config", str(cfg), "--out", str(out / "run"), "--render-every", "100000"]
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True, bufsize=1)
    rows = []
    for line in proc.stdout:
        m = re.match(r"frame\s+(\d+)\s+track loss", line)
        if m and int(m.group(1)) + 1 in marks:
            vm = vm_kb(proc.pid)
            rows.append((int(m.group(1)) + 1, vm["VmRSS"] / 1024, vm["VmHWM"] / 1024, time.perf_counter() - t0))
            print(f"frame {rows[-1][0]}: RSS {rows[-1][1]:.0f} MB, peak {rows[-1][2]:.0f} MB", flush=True)
    proc.wait()
    print(f"\n| frames | RSS MB | peak RSS MB | s |\n|---|---|---|---|")
    for r in rows:
        print(f"| {r[0]} | {r[1]:.0f} | {r[2]:.0f} | {r[3]:.0f} |")
    if len(rows) == 3:
        print(f"growth of peak RSS from frame {rows[1][0]} to {rows[2][0]}: {100 * (rows[2][2] / rows[1][2] - 1):.1f}%")


if __name__ == "__main__":
    main()
