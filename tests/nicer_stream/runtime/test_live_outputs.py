"""A run with Rerun and MCAP sinks logs the map as it grows: renders, keyframes, beta voxels and
meshes at map updates before the last frame; one pose per frame equal to trajectory.tum."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import trimesh

from nicer_stream.config import load
from nicer_stream.io import output_dir as od
from nicer_stream.io.trajectory import read_tum
from nicer_stream.runtime.slam_run import RunRequest, run_slam
from sinks.readback import read_rrd_columns
from tests.sinks.mcap_readback import read_mcap

FRAMES = 14


def test_live_outputs_reach_both_sinks_while_the_run_goes_on(tmp_path, tiny_config):
    rrd, mcap = tmp_path / "rec.rrd", tmp_path / "rec.mcap"
    res = run_slam(RunRequest(source=f"synthetic:room?frames={FRAMES}", out_dir=tmp_path / "out", priors="oracle:clean",
                              config_file=str(tiny_config), sinks=(f"rerun:{rrd}", f"mcap:{mcap}"), live_mesh_every=1,
                              sync=True))  # every map update logged (the sink worker may skip some)
    assert res.exit_code == 0
    t, poses = read_tum(res.out_dir / od.TRAJECTORY_FILE)
    cols = read_rrd_columns(rrd)
    # One camera pose per frame, equal to trajectory.tum.
    cam = cols["/world/camera"]
    assert cam["frame"] == list(range(FRAMES))
    np.testing.assert_allclose(np.concatenate(cam["Transform3D:translation"]), poses[:, :3, 3], atol=1e-5)
    # Map renders, keyframes and meshes logged at map updates before the last frame.
    render_frames = cols["/world/map_camera/image/depth"]["frame"]
    assert len(render_frames) >= 2 and min(render_frames) < FRAMES - 1
    assert min(cols["/world/keyframes"]["frame"]) < FRAMES - 1
    # The live renders at half size; the last, the final map's, at the input's full size (the
    # run's render of its last frame: the closing update has no live render of its own).
    res_col = next(v for k, v in cols["/world/map_camera/image"].items() if "resolution" in k)
    sizes = [tuple(np.asarray(r).ravel().round().astype(int)) for r in res_col]
    depth = np.load(res.out_dir / od.RENDERS_DIR / od.render_name(FRAMES - 1))["depth"]
    full = (depth.shape[1], depth.shape[0])
    assert sizes[-1] == full and all(s == (full[0] // 2, full[1] // 2) for s in sizes[:-1]), sizes
    assert np.allclose(np.asarray(cols["/world/map_camera/image/depth"]["DepthImage:buffer"][-1], dtype=np.uint8)
                       .view(np.float32), depth.ravel())
    assert len(cols["/world/mesh"]["frame"]) >= 2  # coarse ones on the way, the full one at the end
    # Beta values within Eq. 8's range (c2, c0 + c2] (normalised units), lower where mapped more.
    r = load("fast", str(tiny_config)).render
    betas = np.concatenate([np.asarray(b, dtype=np.float64) for b in cols["/world/beta"]["beta"]])
    assert betas.size and betas.min() > r.beta_c2 and betas.max() <= r.beta_c0 + r.beta_c2 + 1e-7
    assert betas.min() < r.beta_c0 + r.beta_c2 - 1e-4
    # The last mesh logged is mesh.ply.
    ply = trimesh.load(res.out_dir / od.MESH_FILE, process=False)
    assert len(cols["/world/mesh"]["Mesh3D:vertex_positions"][-1]) == len(ply.vertices)
    rerun = Path(sys.executable).with_name("rerun")
    v = subprocess.run([str(rerun), "rrd", "verify", str(rrd)], capture_output=True, text=True)
    assert v.returncode == 0, v.stdout + v.stderr
    # The MCAP: the same poses, renders before the last frame's time.
    msgs = read_mcap(mcap)
    assert len(msgs["/camera/pose"]) == FRAMES
    last_ns = msgs["/camera/pose"][-1][0]
    assert msgs["/map/image"] and msgs["/map/image"][0][0] < last_ns
    assert msgs["/keyframes"] and len(msgs["/keyframes"][-1][1].poses) >= 2
    assert len(msgs["/mesh"]) >= 2
    # `convert` of the .rrd gives the MCAP sink's poses, at the same times.
    from nicer_stream.cli.convert_cmd import convert_rrd

    conv = read_mcap(convert_rrd(rrd, tmp_path / "from_rrd.mcap").out)
    assert [t for t, _ in conv["/camera/pose"]] == [t for t, _ in msgs["/camera/pose"]]
    for (_, a), (_, b) in zip(conv["/camera/pose"], msgs["/camera/pose"]):
        pa, pb = a.pose.position, b.pose.position
        assert np.allclose([pa.x, pa.y, pa.z], [pb.x, pb.y, pb.z], atol=1e-5)  # .rrd keeps float32
    assert len(conv["/camera/gt_pose"]) == FRAMES  # the synthetic source has GT: logged under its own name
