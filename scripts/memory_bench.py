"""Memory over a long run (issues 15 and 55): `nicer-stream run` on a long synthetic room with a
cheap configuration (160 px images, 5-iteration mapping calls; `--map-every N`: a keyframe and a
mapping call every N frames instead of the preset's 5, for 3,000 frames in minutes). The
process's RSS and peak RSS are read from /proc when the run has printed the marked number of
tracked frames (default: a quarter, a half and all of `--frames`). A row per mark as it comes,
a line every 100 frames (the pace from the start), then the growth of peak RSS from each mark
to the last. The run is stopped at the last mark: its closing call, end outputs and evaluation
are not what this measures. `--mapping-extra` adds lines to the [mapping] section (e.g. `full_res_keyframes = 0`
to turn the keyframe cap off); `--sink` records as `run --sink` does.

Usage: .venv/bin/python scripts/memory_bench.py --out runs/mem [--frames 3000 --marks 1000,2000,3000]
       [--map-every 25] [--mapping-extra TEXT] [--sink rerun:runs/mem/rec.rrd]
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

# A tracked frame's line: its pose came from the map ('track loss') or the frontend alone.
FRAME_LINE = re.compile(r"^frame\s+(\d+)\s+(?:track loss|frontend pose)")


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
    ap.add_argument("--marks", default=None, help="frame counts to read RSS at, comma-separated (default: N/4, N/2, N)")
    ap.add_argument("--map-every", type=int, default=None, help="a keyframe and a mapping call every this many frames")
    ap.add_argument("--mapping-extra", default="", help="extra lines for the [mapping] section")
    ap.add_argument("--sink", default=None, help="a sink spec, as `run --sink`")
    a = ap.parse_args()
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    cfg = out / "cheap.toml"
    extra = a.mapping_extra.replace("\\n", "\n")
    if a.map_every:
        extra += f"\nevery = {a.map_every}\nkeyframe_every = {a.map_every}"
    cfg.write_text(CHEAP.format(mapping_extra=extra))
    marks = sorted({int(m) for m in a.marks.split(",")} if a.marks else {a.frames // 4, a.frames // 2, a.frames})
    cmd = [sys.executable, "-m", "nicer_stream.cli.main", "run", "--source", f"synthetic:room?frames={a.frames}",
           "--priors", "oracle:clean", "--config", str(cfg), "--out", str(out / "run"), "--render-every", "100000"]
    cmd += ["--sink", a.sink] if a.sink else []
    print(" ".join(cmd), flush=True)
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True, bufsize=1)
    rows, seen = [], 0
    try:
        for line in proc.stdout:
            m = FRAME_LINE.match(line)
            if not m:
                continue
            seen += 1
            if seen in marks:  # frames done, counted as the run reports them (replayed held frames included)
                vm = vm_kb(proc.pid)
                rows.append((seen, vm["VmRSS"] / 1024, vm["VmHWM"] / 1024, time.perf_counter() - t0))
                print(f"frame {seen}: RSS {rows[-1][1]:.0f} MB, peak {rows[-1][2]:.0f} MB, {rows[-1][3]:.0f} s", flush=True)
                if seen == marks[-1]:
                    break
            elif seen % 100 == 0:
                print(f"frame {seen}: {time.perf_counter() - t0:.0f} s", flush=True)
    except KeyboardInterrupt:  # the rows so far are still worth a table
        pass
    proc.terminate()  # a stop: the run writes what it has and exits
    proc.communicate()  # its last lines read, so it never waits on a full pipe
    print("\n| frames | RSS MB | peak RSS MB | s |\n|---|---|---|---|")
    for r in rows:
        print(f"| {r[0]} | {r[1]:.0f} | {r[2]:.0f} | {r[3]:.0f} |")
    for r in rows[:-1]:
        print(f"growth of peak RSS from frame {r[0]} to {rows[-1][0]}: {100 * (rows[-1][2] / r[2] - 1):.1f}%")


if __name__ == "__main__":
    main()
