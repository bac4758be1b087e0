"""Output-directory contract: JSON keys, round trips, one-line errors."""
from __future__ import annotations

import json

import pytest

from nicer_stream.errors import UserError
from nicer_stream.io import output_dir as od

SUMMARY_KEYS = {"frames", "preset", "device", "priors", "wall_s", "stages_s", "seconds_per_frame",
                "peak_rss_mb", "versions", "interrupted"}
EVAL_KEYS = {"ate_rmse_m", "ate_se3_rmse_m", "rpe_trans_m", "rpe_rot_deg", "depth_l1_m", "psnr_db", "ssim",
             "priors", "sim3_scale", "scene_scale", "scene_alignment", "depth_l1_pose_aligned_m", "evaluated_views",
             "mesh", "mesh_pose_aligned", "heldout"}
MESH_KEYS = {"acc_m", "comp_m", "comp_ratio", "normal_consistency", "reference"}


def summary(**kw) -> od.Summary:
    base = dict(
        frames=20, preset="fast", device="cpu", priors=["oracle"], wall_s=12.5,
        stages_s=od.StageSeconds(tracking=4.0, mapping=6.0, priors=1.5, sinks=1.0),
        seconds_per_frame=0.625, peak_rss_mb=812.0, versions={"torch": "2.13.0"}, interrupted=False,
    )
    return od.Summary(**{**base, **kw})


def test_file_names():
    assert (od.TRAJECTORY_FILE, od.MESH_FILE, od.SUMMARY_FILE, od.EVAL_FILE, od.RENDERS_DIR) == (
        "trajectory.tum", "mesh.ply", "summary.json", "eval.json", "renders")
    assert od.render_name(7) == "frame_000007.npz"


def test_summary_round_trip_and_keys(tmp_path):
    s = summary(bound=od.Bound(centre=[0.1, 0.2, 0.3], half_extent=2.5, source="depth_prior"), notes=["x"])
    path = od.write_summary(tmp_path, s)
    data = json.loads(path.read_text())
    assert SUMMARY_KEYS <= data.keys()
    assert set(data["stages_s"]) == {"tracking", "frontend", "mapping", "priors", "sinks"}
    assert set(data["bound"]) == {"centre", "half_extent", "source"}
    assert od.read_summary(tmp_path) == s
    od.write_summary(tmp_path, summary())
    assert od.read_summary(tmp_path).bound is None


def test_summary_ignores_unknown_keys_and_reports_missing(tmp_path):
    data = json.loads(od.write_summary(tmp_path, summary()).read_text())
    data["future_key"] = 1
    (tmp_path / od.SUMMARY_FILE).write_text(json.dumps(data))
    assert od.read_summary(tmp_path) == summary()
    del data["wall_s"]
    (tmp_path / od.SUMMARY_FILE).write_text(json.dumps(data))
    with pytest.raises(UserError, match="wall_s") as e:
        od.read_summary(tmp_path)
    assert "\n" not in str(e.value)


@pytest.mark.parametrize("content", ["{not json", "[1, 2]"])
def test_malformed_summary_is_one_line_user_error(tmp_path, content):
    (tmp_path / od.SUMMARY_FILE).write_text(content)
    with pytest.raises(UserError) as e:
        od.read_summary(tmp_path)
    assert "\n" not in str(e.value) and "summary.json" in str(e.value)


def test_missing_summary(tmp_path):
    with pytest.raises(UserError, match="summary.json"):
        od.read_summary(tmp_path)


def test_bad_bound_source():
    with pytest.raises(UserError):
        od.Bound(centre=[0, 0, 0], half_extent=1.0, source="gt")


def test_eval_round_trip_keys_and_nulls(tmp_path):
    rep = od.EvalReport(
        ate_rmse_m=0.01, psnr_db=float("inf"), ssim=0.9, priors=["oracle"], sim3_scale=1.2,
        evaluated_views=od.EvaluatedViews([0, 5], 160, 91),
        mesh=od.MeshReport(0.02, 0.03, 0.9, 0.8, "gt_depth_points"),
        heldout=od.HeldOutReport(psnr_db=25.0, frame_indices=[3]),
    )
    data = json.loads(od.write_eval(tmp_path, rep).read_text())
    assert set(data) == EVAL_KEYS and set(data["mesh"]) == MESH_KEYS
    assert data["psnr_db"] is None and data["depth_l1_m"] is None  # inf and missing -> null
    assert data["evaluated_views"]["frame_indices"] == [0, 5] and "GT-valid" in data["evaluated_views"]["pixel_rule"]
    back = od.read_eval(tmp_path)
    assert back.mesh == rep.mesh and back.evaluated_views == rep.evaluated_views and back.heldout == rep.heldout
    assert data["heldout"]["lpips"] is None and "LPIPS" in data["heldout"]["note"]
    assert back.ate_rmse_m == 0.01 and back.psnr_db is None
