"""scripts/eval_table.py on hand-made output directories: rows, the scale gap, the mean row."""
import subprocess
import sys
from pathlib import Path

from nicer_stream.io import output_dir as od

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "eval_table.py"


def _out(path: Path, ate: float, psnr: float | None, sim3: float | None, scene: float | None, acc: float) -> Path:
    path.mkdir()
    od.write_eval(path, od.EvalReport(
        ate_rmse_m=ate, depth_l1_m=0.03, depth_l1_pose_aligned_m=0.05, psnr_db=psnr, sim3_scale=sim3,
        scene_scale=scene, scene_alignment="icp",
        mesh=od.MeshReport(acc_m=acc, comp_m=0.02, comp_ratio=0.9),
        mesh_pose_aligned=od.MeshReport(acc_m=2 * acc, comp_m=0.04, comp_ratio=0.5)))
    return path


def _table(*args) -> list[str]:
    res = subprocess.run([sys.executable, str(SCRIPT), *map(str, args)], capture_output=True, text=True)
    assert res.returncode == 0, res.stderr
    return res.stdout.splitlines()


def test_rows_gap_and_means(tmp_path):
    a = _out(tmp_path / "a", 0.002, 30.0, 1.40, 1.372, 0.03)  # map 2% below the trajectory's scale
    b = _out(tmp_path / "b", 0.004, 28.0, 1.35, 1.35, 0.05)
    lines = _table(a, b)
    assert lines[0].startswith("| run | ATE cm |") and "| PSNR dB | scale gap |" in lines[0] and len(lines) == 5
    assert lines[2] == f"| {a} | 0.20 | 3.00 (5.00) | 3.00 (6.00) | 2.00 (4.00) | 90.0% (50.0%) | 30.00 | -2.0% | icp | - |"
    assert lines[3].split(" | ")[6:8] == ["28.00", "+0.0%"]
    assert lines[4] == "| mean of 2 | 0.30 | 3.00 (5.00) | 4.00 (8.00) | 2.00 (4.00) | 90.0% (50.0%) | 29.00 | -1.0% |  | - |"


def test_one_run_has_no_mean_and_missing_values_stay_blank(tmp_path):
    a = _out(tmp_path / "a", 0.002, None, None, None, 0.03)
    b = _out(tmp_path / "b", 0.002, 29.0, 1.3, 1.3, 0.03)
    assert len(_table(a)) == 3
    mean = _table(a, b)[-1].split(" | ")
    assert mean[0] == "| mean of 2" and mean[6:8] == ["-", "-"]  # a has neither PSNR nor scales
