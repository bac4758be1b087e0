"""The coarse-to-fine SDF grid gives marching cubes the dense grid's input: the same meshes, for
a fraction of the SDF calls, also for an SDF that jumps where a mask ends (as scene_mesh's)."""
from dataclasses import replace

import numpy as np
import pytest
import torch

from nicer_stream.mesh import extract
from nicer_stream.mesh.extract import _grid_axes, extract_mesh
from nicer_stream.mesh.sparse_grid import _sdf_values, evaluate_grid_sparse, mixed_voxel_boxes

LO, HI = [-1.0, -0.9, -1.1], [1.0, 1.2, 0.95]


def evaluate_grid(sdf_fn, axes: list[np.ndarray], chunk: int, device) -> np.ndarray:
    """(R_x, R_y, R_z) float32 volume of sdf_fn at every grid point: the dense reference (moved here
    from mesh/sparse_grid.py, which only the tests asked for), a few x-planes at a time."""
    shape = tuple(len(a) for a in axes)
    ax = [torch.as_tensor(a, dtype=torch.float32, device=device) for a in axes]
    out = np.empty(shape, dtype=np.float32)
    planes = max(1, chunk // (shape[1] * shape[2]))
    with torch.no_grad():
        for i0 in range(0, shape[0], planes):
            i1 = min(i0 + planes, shape[0])
            pts = torch.stack(torch.meshgrid(ax[0][i0:i1], ax[1], ax[2], indexing="ij"), dim=-1).reshape(-1, 3)
            out[i0:i1] = _sdf_values(sdf_fn, pts, chunk).reshape(i1 - i0, *shape[1:])
    return out


def on_dense_grid(fn, *args, **kwargs):
    """`fn(*args, **kwargs)` (extract_mesh, or scene_mesh through it) on the dense grid: every
    point evaluated (jump_fn then plays no part)."""
    with pytest.MonkeyPatch.context() as m:
        m.setattr(extract, "evaluate_grid_sparse",
                  lambda sdf_fn, axes, chunk, device, jump_fn=None: evaluate_grid(sdf_fn, axes, chunk, device))
        return fn(*args, **kwargs)


def _sphere(centre, radius):
    c = torch.tensor(centre)
    return lambda p: (p - c.to(p)).norm(dim=-1) - radius


def _box(p, half=torch.tensor([0.5, 0.3, 0.4])):
    q = p.abs() - half
    return q.clamp_min(0).norm(dim=-1) + q.max(dim=-1).values.clamp_max(0)


def _two_spheres(p):
    # The second sphere's radius is about a cell at the resolutions below: far thinner than a block.
    return torch.minimum(_sphere([0.2, -0.1, 0.0], 0.45)(p), _sphere([-0.53, 0.61, 0.43], 0.04)(p))


def _plane(p):
    return p @ torch.tensor([0.3, -0.5, 0.8]) - 0.05


SDFS = {"sphere": _sphere([0.1, -0.2, 0.05], 0.6), "box": _box, "two_spheres": _two_spheres, "plane": _plane}


class Counted:
    """sdf_fn counting the points it is called on."""

    def __init__(self, fn):
        self.fn, self.points = fn, 0

    def __call__(self, p):
        self.points += len(p)
        return self.fn(p)


def _near_crossings(v: np.ndarray) -> np.ndarray:
    """(R, R, R) bool: the corners of the cells whose corners are not all > 0 or all <= 0."""
    pos = v > 0
    cells = np.zeros([n - 1 for n in v.shape], dtype=bool)
    first = pos[:-1, :-1, :-1]
    for a in (0, 1):
        for b in (0, 1):
            for c in (0, 1):
                cells |= pos[a : a + cells.shape[0], b : b + cells.shape[1], c : c + cells.shape[2]] != first
    out = np.zeros(v.shape, dtype=bool)
    for a in (0, 1):
        for b in (0, 1):
            for c in (0, 1):
                out[a : a + cells.shape[0], b : b + cells.shape[1], c : c + cells.shape[2]] |= cells
    return out


def _assert_same_surface(sparse: np.ndarray, dense: np.ndarray) -> None:
    """Same signs everywhere and the same values at every corner of a cell with a zero crossing."""
    assert np.array_equal(sparse > 0, dense > 0)
    near = _near_crossings(dense)
    assert near.any()
    np.testing.assert_array_equal(sparse[near], dense[near])


def _assert_same_mesh(a, b) -> None:
    assert len(a.faces) > 0
    # The same faces; vertices to float rounding (the SDF of a block and of the whole grid go
    # through numpy/torch passes of other lengths: on an AVX-512 CPU 1-ulp apart).
    assert np.array_equal(a.faces, b.faces)
    np.testing.assert_allclose(a.vertices, b.vertices, rtol=0, atol=1e-6)


@pytest.mark.parametrize("name", sorted(SDFS))
@pytest.mark.parametrize("resolution", [23, 48, 61])
def test_sparse_and_dense_grids_give_the_same_mesh(name, resolution):
    sdf = SDFS[name]
    dense_mesh = on_dense_grid(extract_mesh, sdf, None, LO, HI, resolution, chunk=5000)
    _assert_same_mesh(extract_mesh(sdf, None, LO, HI, resolution, chunk=5000), dense_mesh)


@pytest.mark.parametrize("block", [1, 2, 4, 8, 32])
def test_every_block_size_keeps_the_values_at_every_crossing(block):
    axes = _grid_axes(LO, HI, 45)  # 44 cells: blocks of 8 and 32 end short
    dense = evaluate_grid(_two_spheres, axes, 4096, None)
    sparse = evaluate_grid_sparse(_two_spheres, axes, 4096, None, block=block)
    _assert_same_surface(sparse, dense)
    if block == 1:
        np.testing.assert_array_equal(sparse, dense)


def test_the_check_sees_a_skipped_surface():
    # Without the margin, a block whose corners are all outside the small sphere is not refined:
    # the sphere is lost, and the comparison above says so.
    axes = _grid_axes(LO, HI, 45)
    dense = evaluate_grid(_two_spheres, axes, 4096, None)
    sparse = evaluate_grid_sparse(_two_spheres, axes, 4096, None, margin=0.0)
    with pytest.raises(AssertionError):
        _assert_same_surface(sparse, dense)


MASK_LO, MASK_HI = torch.tensor([-0.55, -0.43, 0.07]), torch.tensor([0.62, 0.5, 0.16])


def _in_mask(p):
    return ((p >= MASK_LO) & (p <= MASK_HI)).all(dim=-1)


def _masked_sphere(p):
    """scene_mesh's kind of SDF: a sphere's inside the mask (a slab thinner than a block, not on
    the grid), exactly 1 outside it."""
    out = torch.ones(len(p))
    inside = _in_mask(p)
    out[inside] = _sphere([0.05, 0.0, 0.1], 0.6)(p[inside])
    return out


def _mask_jumps(lo, hi):
    inside = ((lo >= MASK_LO) & (hi <= MASK_HI)).all(dim=-1)
    outside = ((hi < MASK_LO) | (lo > MASK_HI)).any(dim=-1)
    return ~inside & ~outside


@pytest.mark.parametrize("resolution", [40, 61])
def test_an_sdf_jumping_at_a_mask_gives_the_dense_mesh_when_the_jumps_are_declared(resolution):
    dense_mesh = on_dense_grid(extract_mesh, _masked_sphere, None, LO, HI, resolution)
    _assert_same_mesh(extract_mesh(_masked_sphere, None, LO, HI, resolution, jump_fn=_mask_jumps), dense_mesh)
    # Undeclared, the slab falls between the coarse lattice's points (all 1): no surface at all.
    assert len(extract_mesh(_masked_sphere, None, LO, HI, resolution).faces) == 0


def test_sparse_calls_the_sdf_on_a_fraction_of_the_points():
    sdf = Counted(_sphere([0.1, -0.2, 0.05], 0.5))
    axes = _grid_axes([-1] * 3, [1] * 3, 96)
    evaluate_grid_sparse(sdf, axes, 65536, None)
    assert sdf.points < 0.25 * 96**3  # 0.19
    mesh = extract_mesh(sdf, None, [-1] * 3, [1] * 3, 96)
    assert mesh.is_watertight


def test_no_zero_crossing_gives_an_empty_mesh_like_the_dense_grid():
    for offset in (3.0, -5.0):  # |p| <= sqrt(3) in the box: all outside, all inside, far from 0
        sdf = Counted(lambda p: p.norm(dim=-1) + offset)
        mesh = extract_mesh(sdf, None, [-1] * 3, [1] * 3, 50)
        assert len(mesh.vertices) == 0 and len(mesh.faces) == 0
        assert sdf.points < 0.01 * 50**3  # the first lattice is enough


def test_non_finite_samples_are_refined_and_kept():
    def sdf(p):
        out = _sphere([0.0, 0.0, 0.0], 0.5)(p)
        out[(p[:, 0] > 0.8) & (p[:, 1] > 0.8)] = float("nan")
        return out

    axes = _grid_axes(LO, HI, 37)
    dense = evaluate_grid(sdf, axes, 4096, None)
    sparse = evaluate_grid_sparse(sdf, axes, 4096, None)
    assert np.array_equal(np.isnan(sparse), np.isnan(dense)) and np.isnan(dense).any()
    _assert_same_surface(sparse, dense)


def test_mixed_voxel_boxes_matches_counting_by_hand():
    gen = torch.Generator().manual_seed(0)
    mask = torch.rand(7, 5, 6, generator=gen) < 0.1
    mask[:3, :3, :3] = True
    a = torch.stack([torch.randint(0, n, (300,), generator=gen) for n in mask.shape], dim=-1)
    b = torch.stack([torch.randint(0, n, (300,), generator=gen) for n in mask.shape], dim=-1)
    first, last = torch.minimum(a, b), torch.maximum(a, b)
    first[0], last[0] = torch.tensor([0, 0, 0]), torch.tensor([2, 2, 2])  # all True
    got = mixed_voxel_boxes(mask, first, last)
    want = [bool(0 < mask[f[0] : l[0] + 1, f[1] : l[1] + 1, f[2] : l[2] + 1].sum() < (l - f + 1).prod())
            for f, l in zip(first, last)]
    assert got.tolist() == want and not got[0] and 0 < sum(want) < len(want)


def test_bad_block_is_an_error():
    with pytest.raises(ValueError, match="power of two"):
        evaluate_grid_sparse(_plane, _grid_axes(LO, HI, 9), 100, None, block=6)


@pytest.fixture()
def small_scene(tiny_config):
    from nicer_stream.config import load
    from nicer_stream.model.bound import SceneBound
    from nicer_stream.model.scene import SceneModel
    from nicer_stream.render.beta import BetaField
    from nicer_stream.types import Intrinsics

    cfg = load("fast", tiny_config)
    cfg = replace(cfg, mesh=replace(cfg.mesh, resolution=53))
    torch.manual_seed(0)
    model, beta = SceneModel(cfg.model, SceneBound((0.3, -0.2, 1.0), 1.5, "config")), BetaField(cfg.render)
    n = cfg.render.beta_voxels
    with torch.no_grad():  # observed: a block of voxels, a hole in it and scattered single voxels
        counts = beta.counts.view(n, n, n)
        counts[n // 5 : 4 * n // 5, n // 4 : 3 * n // 4, n // 6 : n - 2] = 1.0
        counts[n // 2 : n // 2 + 3, n // 2 : n // 2 + 2, n // 3 : n // 3 + 4] = 0.0
        counts.view(-1)[torch.randperm(n**3)[: n**3 // 50]] = 1.0
    intr = Intrinsics(fx=30.0, fy=30.0, cx=23.5, cy=17.5, width=48, height=36)
    poses = np.tile(np.eye(4), (3, 1, 1))
    poses[:, :3, 3] = [[0.3, -0.2, 1.0], [0.5, -0.2, 1.0], [0.3, 0.0, 0.8]]
    return model, beta, poses, intr, cfg


def test_scene_mesh_is_the_same_from_the_sparse_grid(small_scene):
    from nicer_stream.runtime.scene_export import scene_mesh

    sparse = scene_mesh(*small_scene)
    dense_mesh = on_dense_grid(scene_mesh, *small_scene)
    _assert_same_mesh(sparse, dense_mesh)
    assert np.array_equal(sparse.visual.vertex_colors, dense_mesh.visual.vertex_colors)


def test_scene_mesh_stops_when_asked(small_scene):
    from nicer_stream.runtime.scene_export import MeshAborted, scene_mesh

    calls = []

    def should_stop():
        calls.append(1)
        return len(calls) > 2

    with pytest.raises(MeshAborted):
        scene_mesh(*small_scene, should_stop=should_stop)
    assert len(calls) == 3
