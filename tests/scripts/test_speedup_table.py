"""scripts/speedup_table.py on hand-made output directories."""
import subprocess
import sys
from pathlib import Path

from nicer_stream.io import output_dir as od

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "speedup_table.py"


def _out(path: Path, wall_s: float, frames: int, track: float, mapping: float, ate: float | None,
         time_txt: str | None = None) -> Path:
    path.mkdir()
    od.write_summary(path, od.Summary(
        frames=frames, preset="fast", device="cpu", priors=["oracle"], wall_s=wall_s, stages_s=od.StageSeconds(),
        seconds_per_frame=wall_s / frames, peak_rss_mb=900.0, versions={}, interrupted=False,
        stats={"tracking_s_per_frame": track, "mapping_s_per_frame": mapping}))
    if ate is not None:
        od.write_eval(path, od.EvalReport(ate_rmse_m=ate))
    if time_txt is not None:
        (path / "time.txt").write_text(time_txt)
    return path


def _table(*args) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(SCRIPT), *map(str, args)], capture_output=True, text=True)


def test_table_rows_and_speedup(tmp_path):
    base = _out(tmp_path / "base", 900.0, 20, 20.0, 24.0, 0.0123, "905.31 812345\n")
    new = _out(tmp_path / "new", 300.0, 20, 6.0, 8.5, None)  # no eval.json, no time.txt
    res = _table(base, new, "--labels", "c64946b", "036e188+edits")
    assert res.returncode == 0, res.stderr
    lines = res.stdout.splitlines()
    assert lines[0].startswith("| commit | process s | wall_s | frames | s/frame |") and len(lines) == 4
    assert lines[2] == "| c64946b | 905 | 900 | 20 | 45.00 | 20.00 | 24.00 | 1.23 | 1.00 |"
    assert lines[3] == "| 036e188+edits | - | 300 | 20 | 15.00 | 6.00 | 8.50 | - | 3.00 |"


def test_default_labels_and_errors(tmp_path):
    base = _out(tmp_path / "base", 10.0, 5, 1.0, 1.0, 0.01, "Command exited with non-zero status 1\n12.5 1000\n")
    res = _table(base, base)
    assert res.returncode == 0 and res.stdout.splitlines()[2].startswith("| base | 12 | 10 | 5 | 2.00 |")
    res = _table(base, tmp_path / "missing")
    assert res.returncode != 0 and "summary.json not found" in res.stderr and "Traceback" not in res.stderr
    assert _table(base, base, "--labels", "one").returncode == 2
