"""The SDF sample grid for marching cubes, coarse to fine near the surface (the tests hold the dense one).

A grid is three (R_a,) float64 axes (world coordinates, evenly spaced, ends included) and a
volume (R_x, R_y, R_z) float32 with volume[i, j, k] = sdf(x_i, y_j, z_k).

Why coarse to fine: marching cubes only looks at the cells with a zero crossing, a thin shell
around the surface, yet the dense grid calls sdf_fn (a network) at all R^3 points; most of
a mesh extraction's time went there.

How: a *lattice* of step b holds the grid indices 0, b, 2 b, ... and the last one on each axis;
it cuts the cells into blocks of b^3 cells (smaller at the upper ends). sdf_fn is evaluated on
the lattice of step `block` (a power of two); a block is *active* when one of its 8 corners is
non-finite or has |sdf| < margin * D_b (D_b: the world diagonal of a full block of step b), when
its corners do not all have the same strict sign, or when `jump_fn` says sdf_fn may jump inside
it. The lattice of step b / 2 then takes sdf_fn's values at its new points in active blocks and
the trilinear interpolation of the block's corners in inactive ones; its blocks inside active
blocks are tested the same way, and so on down to step 1, the grid itself.

Why the mesh is the dense grid's: any point of a block is within D_b / 2 of one of its corners,
so an sdf_fn that is L-Lipschitz with L < 2 * margin has the corners' sign at every point of an
inactive block (a true SDF has L = 1; a network trained with an Eikonal term is about 1 but not
exactly: the default margin 2 allows L < 4). The interpolated values there have that sign too,
so a cell with a zero crossing in either volume lies in active blocks at every step: its 8
corners hold sdf_fn's own values, and marching cubes ignores all other cells. The Lipschitz
bound is only needed inside each box that `jump_fn` clears: an sdf_fn that is a constant outside
observed voxels, say, is evaluated densely across their border.
"""
from __future__ import annotations

from typing import Callable

import numpy as np
import torch

SdfFn = Callable[[torch.Tensor], torch.Tensor]
JumpFn = Callable[[torch.Tensor, torch.Tensor], torch.Tensor]

BLOCK = 8
"""Step of the first (coarsest) lattice, in grid cells."""
MARGIN = 2.0
"""A block with a corner |sdf| below MARGIN of its diagonals is refined."""


def _chunked(fn, chunk: int, *args: torch.Tensor) -> torch.Tensor:
    """(N, ...) CPU tensor: fn(*args) (each (N, ...)) called on at most `chunk` rows at a time."""
    n = len(args[0])
    if n == 0:
        return torch.empty(0)
    return torch.cat([fn(*[a[s : s + chunk] for a in args]).reshape(-1).cpu() for s in range(0, n, chunk)])


def _sdf_values(sdf_fn: SdfFn, pts: torch.Tensor, chunk: int) -> np.ndarray:
    """(N,) float32 sdf_fn at points (N, 3)."""
    return _chunked(sdf_fn, chunk, pts).float().numpy()


def _points(ax: list[torch.Tensor], ijk) -> torch.Tensor:
    """(N, 3) points at index arrays (i, j, k), each (N,), into the axes `ax`."""
    return torch.stack([a[torch.as_tensor(i, device=a.device)] for a, i in zip(ax, ijk)], dim=-1)


def _lattice(n: int, step: int) -> np.ndarray:
    """Grid indices 0, step, 2 step, ... and n - 1 of an axis of n points."""
    return np.unique(np.r_[np.arange(0, n, step), n - 1])


class _Refinement:
    """One axis from a lattice to a finer one: `coarse` (C,) and `fine` (F,) grid indices,
    coarse a subset of fine. For every fine index m, `lo[m]` is the coarse block holding fine[m]
    (the upper one where two share it), `hi[m]` the one holding it from below, `t[m]` its
    fraction of the way through block lo[m]; `on_coarse[m]` says whether fine[m] is in coarse."""

    def __init__(self, coarse: np.ndarray, fine: np.ndarray) -> None:
        self.coarse, self.fine = coarse, fine
        last = len(coarse) - 2
        self.lo = np.minimum(np.searchsorted(coarse, fine, side="right") - 1, last)
        self.hi = np.maximum(np.searchsorted(coarse, fine, side="left") - 1, 0)
        self.t = ((fine - coarse[self.lo]) / (coarse[self.lo + 1] - coarse[self.lo])).astype(np.float32)
        self.on_coarse = np.isin(fine, coarse)

    def interpolate(self, v: np.ndarray, axis: int) -> np.ndarray:
        """v with `axis` of length C -> F, linear between the coarse indices."""
        t = self.t.reshape([-1 if a == axis else 1 for a in range(v.ndim)])
        return np.take(v, self.lo, axis) * (1 - t) + np.take(v, self.lo + 1, axis) * t

    def expand(self, blocks: np.ndarray, axis: int) -> np.ndarray:
        """Coarse-block bools with `axis` of length C - 1 -> fine-index bools: in a true block."""
        return np.take(blocks, self.lo, axis) | np.take(blocks, self.hi, axis)


def _to_refine(v: np.ndarray, threshold: float) -> np.ndarray:
    """(C_x - 1, C_y - 1, C_z - 1) bool of lattice values v (C_x, C_y, C_z): True for the blocks
    with a non-finite corner, a corner with |v| < threshold, or corners not all of one strict sign."""
    blocks = tuple(n - 1 for n in v.shape)
    calm, pos, neg = np.ones(blocks, bool), np.ones(blocks, bool), np.ones(blocks, bool)
    for a in (0, 1):
        for b in (0, 1):
            for c in (0, 1):
                w = v[a : a + blocks[0], b : b + blocks[1], c : c + blocks[2]]
                calm &= np.isfinite(w) & (np.abs(w) >= threshold)
                pos &= w > 0
                neg &= w < 0
    return ~(calm & (pos | neg))


def _jumps(jump_fn: JumpFn | None, ax: list[torch.Tensor], idx: list[np.ndarray], which: np.ndarray,
           chunk: int) -> np.ndarray:
    """Bool like `which` (blocks of the lattice idx): jump_fn of the blocks `which` selects."""
    out = np.zeros_like(which)
    if jump_fn is None:
        return out
    ijk = np.nonzero(which)
    lo = _points(ax, [c[i] for c, i in zip(idx, ijk)])
    hi = _points(ax, [c[i + 1] for c, i in zip(idx, ijk)])
    out[ijk] = _chunked(jump_fn, chunk, lo, hi).numpy().astype(bool)
    return out


def _refine(sdf_fn: SdfFn, v: np.ndarray, active: np.ndarray, axes: list[_Refinement],
            ax: list[torch.Tensor], chunk: int) -> np.ndarray:
    """Lattice values v (C_x, C_y, C_z) -> (F_x, F_y, F_z) on the finer lattice: sdf_fn at the new
    points of the `active` blocks (C_x - 1, C_y - 1, C_z - 1), trilinear in v elsewhere."""
    rx, ry, rz = axes
    fax = [a[torch.as_tensor(r.fine, device=a.device)] for a, r in zip(ax, axes)]
    # Non-finite corners only occur in active blocks, whose points are all evaluated;
    # zeros keep them out of the neighbouring blocks' interpolation.
    fill = rx.interpolate(np.where(np.isfinite(v), v, 0).astype(np.float32), 0)
    need = rx.expand(active, 0)
    out = np.empty((len(rx.fine), len(ry.fine), len(rz.fine)), dtype=np.float32)
    old = ry.on_coarse[:, None] & rz.on_coarse[None, :]
    # A few x-planes at a time bounds the memory (a full (R^3, 3) array of points: 1.6 GB at R = 512).
    planes = max(1, 4 * chunk // (out.shape[1] * out.shape[2]))
    for i0 in range(0, len(out), planes):
        i1 = min(i0 + planes, len(out))
        out[i0:i1] = rz.interpolate(ry.interpolate(fill[i0:i1], 1), 2)
        todo = rz.expand(ry.expand(need[i0:i1], 1), 2) & ~(rx.on_coarse[i0:i1, None, None] & old)
        i, j, k = np.nonzero(todo)
        out[i0:i1][i, j, k] = _sdf_values(sdf_fn, _points(fax, (i + i0, j, k)), chunk)
    out[np.ix_(rx.on_coarse, ry.on_coarse, rz.on_coarse)] = v
    return out


def evaluate_grid_sparse(
    sdf_fn: SdfFn,
    axes: list[np.ndarray],
    chunk: int,
    device,
    block: int = BLOCK,
    margin: float = MARGIN,
    jump_fn: JumpFn | None = None,
) -> np.ndarray:
    """(R_x, R_y, R_z) float32 volume of sdf_fn at the grid points, evaluated coarse to fine
    only near its zero crossings (see the module docstring); trilinear elsewhere.

    block: the first lattice's step, a power of two (1: the dense grid). margin: in block
    diagonals, the |sdf| below which a block is refined; sdf_fn must be L-Lipschitz with
    L < 2 margin inside every box jump_fn clears.
    jump_fn: boxes lo (B, 3), hi (B, 3) world corners -> (B,) bool, True where sdf_fn may be
    discontinuous inside [lo, hi] (such blocks are refined); None: continuous everywhere.
    """
    if block < 1 or block & (block - 1):
        raise ValueError(f"block must be a power of two, got {block}")
    shape = tuple(len(a) for a in axes)
    ax = [torch.as_tensor(a, dtype=torch.float32, device=device) for a in axes]
    cell_diag = float(np.linalg.norm([a[1] - a[0] for a in axes]))
    idx = [_lattice(n, block) for n in shape]
    with torch.no_grad():
        ijk = [g.reshape(-1) for g in np.meshgrid(*idx, indexing="ij")]
        v = _sdf_values(sdf_fn, _points(ax, ijk), chunk).reshape([len(c) for c in idx])
        active = _to_refine(v, margin * block * cell_diag)
        active |= _jumps(jump_fn, ax, idx, ~active, chunk)
        while block > 1:
            block //= 2
            steps = [_Refinement(c, _lattice(n, block)) for c, n in zip(idx, shape)]
            v = _refine(sdf_fn, v, active, steps, ax, chunk)
            idx = [r.fine for r in steps]
            if block > 1:
                parent = active[np.ix_(*[r.lo[:-1] for r in steps])]
                active = parent & _to_refine(v, margin * block * cell_diag)
                active |= _jumps(jump_fn, ax, idx, parent & ~active, chunk)
    return v


def mixed_voxel_boxes(mask: torch.Tensor, first: torch.Tensor, last: torch.Tensor) -> torch.Tensor:
    """(B,) bool: the boxes mask[first[b, 0] : last[b, 0] + 1, (same on axes 1, 2)] hold both
    True and False voxels. mask (X, Y, Z) bool; first, last (B, 3) integer, first <= last.
    Counts by a summed-area table: O(B) after O(X Y Z), whatever the boxes' sizes."""
    sat = torch.nn.functional.pad(mask.long().cumsum(0).cumsum(1).cumsum(2), (1, 0, 1, 0, 1, 0))
    first, last = first.long(), last.long() + 1
    count = torch.zeros(len(first), dtype=torch.long, device=mask.device)
    for corner in range(8):
        pick = [(corner >> a) & 1 for a in range(3)]
        ends = [(last if p else first)[:, a] for a, p in enumerate(pick)]
        count += (-1) ** (3 - sum(pick)) * sat[ends[0], ends[1], ends[2]]
    return (count > 0) & (count < (last - first).prod(dim=-1))
