"""The outdoor `street` scene: depth range, sky, trajectory, render/mesh agreement, grey frames (sources/synthetic)."""
from __future__ import annotations

import time

import numpy as np
import pytest
import torch

from nicer_stream.errors import SourceError
from nicer_stream.geometry import camera, se3
from sources import open_source
from tests.sources.synthetic.scene_geometry import bounds, clearance
from sources.synthetic import default_intrinsics, make_scene
from sources.synthetic.street import STEP

SMALL = default_intrinsics(160, 120)
MID = 75


@pytest.fixture(scope="module")
def street():
    return make_scene("street", 0)


@pytest.fixture(scope="module")
def mid_view(street):
    T = street.trajectory(150)[MID]
    return T, street.render(T, SMALL)


def _world_dirs(T: np.ndarray, intr) -> np.ndarray:
    """(H*W, 3) unit world ray directions of the pixel centres (nicer_stream's camera model, not the renderer's)."""
    d = camera.camera_dirs(camera.pixel_grid(intr, dtype=torch.float64), intr).numpy()
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    return d @ T[:3, :3].T


def _mesh_ray_dist(mesh, o: np.ndarray, dirs: np.ndarray) -> np.ndarray:
    """(R,) distance along unit rays `dirs` (R, 3) from `o` (3,) to the first triangle hit (inf = miss).

    Moller-Trumbore against every triangle: independent of the renderer and needs no spatial index.
    """
    v0, v1, v2 = (np.asarray(mesh.vertices)[mesh.faces[:, k]] for k in range(3))
    e1, e2, s = v1 - v0, v2 - v0, o - v0
    q = np.cross(s, e1)
    out = np.full(len(dirs), np.inf)
    for r, d in enumerate(dirs):
        p = np.cross(d, e2)
        det = np.einsum("ij,ij->i", e1, p)
        inv = 1.0 / np.where(np.abs(det) < 1e-12, 1e-12, det)
        u, v, t = np.einsum("ij,ij->i", s, p) * inv, (q @ d) * inv, np.einsum("ij,ij->i", e2, q) * inv
        ok = (np.abs(det) > 1e-12) & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 1e-6)
        if ok.any():
            out[r] = t[ok].min()
    return out


def test_depth_spans_near_road_to_far_facades_with_sky(street, mid_view):
    T, view = mid_view
    valid = view.depth > 0
    assert view.depth[valid].min() < 5.0 and view.depth[valid].max() > 40.0
    assert np.percentile(view.depth[valid], 50) < 20.0  # mostly nearby road and facades
    sky = ~valid
    assert 0.02 < sky.mean() < 0.5
    assert sky[: SMALL.height // 2].mean() > 5 * sky[SMALL.height // 2 :].mean()  # the sky is up
    expected = street.sky(_world_dirs(T, SMALL).T).T.reshape(SMALL.height, SMALL.width, 3)
    np.testing.assert_allclose(view.rgb[sky], expected[sky], atol=2e-3)
    assert (view.rgb[sky][:, 2] > view.rgb[sky][:, 0] + 0.05).all()  # blue
    assert (view.normal[sky] == 0).all() and (view.depth[sky] == 0).all()


def test_trajectory_drives_forward_along_the_street(street):
    T = street.trajectory(200)
    R, t = T[:, :3, :3], T[:, :3, 3]
    assert np.allclose(R @ R.transpose(0, 2, 1), np.eye(3), atol=1e-9) and np.allclose(np.linalg.det(R), 1)
    motion = np.diff(t, axis=0)
    step = np.linalg.norm(motion, axis=-1)
    assert (0.5 < step).all() and (step < 1.5).all()
    np.testing.assert_allclose(motion[:, 0], STEP)  # fixed metres per frame along the street
    fwd = R[:-1, :, 2]  # camera z axis in the world
    assert (np.einsum("ni,ni->n", fwd, motion / step[:, None]) > np.cos(np.radians(10))).all()
    assert np.abs(t[:, 2] - 1.5).max() < 0.1 and R[:, 2, 1].max() < -0.99  # 1.5 m up, image y points down
    assert np.ptp(t[:, 1]) > 0.3  # not a pure line
    rel = torch.from_numpy(R[0].T @ R)
    assert np.degrees(se3.rotation_angle(rel).numpy()).max() > 2.0  # it yaws a little
    assert clearance(street, t).min() > 1.0
    np.testing.assert_array_equal(street.trajectory(40), T[:40])  # prefix: the same poses for any N
    with pytest.raises(SourceError) as e:
        street.trajectory(10_000)
    assert "frames" in str(e.value) and "\n" not in str(e.value)


def test_render_agrees_with_ray_casting_the_gt_mesh(street, mid_view):
    T, view = mid_view
    t0 = time.perf_counter()
    mesh = street.gt_mesh()
    built = time.perf_counter() - t0
    assert len(mesh.faces) < 1_000_000 and built < 15.0  # target < 5 s; loose because the machine is shared
    lo, hi = bounds(street)
    assert (mesh.vertices >= lo - 1e-6).all() and (mesh.vertices <= hi + 1e-6).all()
    rng = np.random.default_rng(0)
    depth = view.depth.reshape(-1)
    valid, far, sky = np.flatnonzero(depth > 0), np.flatnonzero(depth > 30), np.flatnonzero(depth == 0)
    pix = np.concatenate([rng.choice(idx, k, replace=False) for idx, k in ((valid, 25), (far, 5), (sky, 10))])
    dirs = _world_dirs(T, SMALL)[pix]
    dist = _mesh_ray_dist(mesh, T[:3, 3], dirs)
    z_cam = (dirs @ T[:3, :3])[:, 2]
    hit = depth[pix] > 0
    assert np.isinf(dist[~hit]).all()  # sky: no geometry in that direction
    np.testing.assert_allclose(dist[hit] * z_cam[hit], depth[pix][hit], atol=0.02)


@pytest.mark.parametrize("name", ["street", "room"])
def test_grey_frames_are_the_luminance_in_three_channels(name):
    uri = f"synthetic:{name}?frames=3&width=48&height=36"
    colour, grey = next(iter(open_source(uri))), next(iter(open_source(uri + "&grey=1")))
    assert grey.rgb.shape == (36, 48, 3) and grey.rgb.dtype == np.float32
    assert (grey.rgb[..., 0] == grey.rgb[..., 1]).all() and (grey.rgb[..., 1] == grey.rgb[..., 2]).all()
    luma = colour.rgb @ np.array([0.299, 0.587, 0.114])
    np.testing.assert_allclose(grey.rgb[..., 0], luma, atol=1e-5)
    assert np.abs(colour.rgb[..., 0] - colour.rgb[..., 2]).max() > 0.05  # the colour frame is not grey already
    np.testing.assert_array_equal(grey.gt_depth, colour.gt_depth)
    with pytest.raises(SourceError, match="grey"):
        open_source(uri + "&grey=2")


def test_street_is_deterministic_per_seed():
    uri = "synthetic:street?frames=12&width=48&height=36&seed={}"
    a, b, c = (list(open_source(uri.format(s))) for s in (3, 3, 4))
    assert [f.index for f in a] == list(range(12))
    for fa, fb in zip(a, b):
        assert np.array_equal(fa.rgb, fb.rgb) and np.array_equal(fa.gt_depth, fb.gt_depth)
        assert np.array_equal(fa.gt_pose, fb.gt_pose)
    assert np.abs(a[6].rgb - c[6].rgb).mean() > 0.02
    assert not np.allclose(a[6].gt_pose, c[6].gt_pose)
