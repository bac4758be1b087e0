"""Analytic primitives with exact ray intersection, normals and signed distance (numpy).

Layout: points and directions are **(3, N) arrays** (x, y, z rows). numpy is
several times faster on contiguous rows than on the last axis of (N, 3).
Everything is in world coordinates, metres. Rays are origins `o` ((3,) shared
by all rays, or (3, N)) and unit directions `d` (3, N). A `Hit` holds the ray
distance `t` (N,) (`inf` = miss) and the unit outward normal (3, N) at the hit
(for the inside-out room box: the normal pointing into the room).
Oriented primitives have a local frame: `R` (3, 3, local-to-world) and `centre` (3,).
Every primitive has `extent`: (3,) half sizes of a world axis-aligned box around it, about `centre`.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

_EPS = 1e-6


def linear(M: np.ndarray, v: np.ndarray) -> np.ndarray:
    """M (K, 3) or (3,) applied to v (3, N) -> (K, N) or (N,), in v's dtype.

    einsum instead of `@`: these tall-thin products would go to multithreaded
    BLAS, whose spinning threads cost more CPU than the product on a shared machine.
    """
    return np.einsum("...j,jn->...n", M.astype(v.dtype), v)


@dataclass(frozen=True)
class Hit:
    """t: (N,) ray distance in metres (inf = miss); normal: (3, N) unit world normal."""

    t: np.ndarray
    normal: np.ndarray


def _to_local(o: np.ndarray, d: np.ndarray, centre: np.ndarray, R: np.ndarray):
    """World rays -> local frame: p_local = R^T (p - c). Returns (3, 1 or N) origins, (3, N) directions."""
    ol = linear(R.T, np.reshape(o, (3, -1)) - centre[:, None])
    return ol.astype(d.dtype), linear(R.T, d)


def _safe_inv(x: np.ndarray) -> np.ndarray:
    """1 / x with exact zeros nudged, so that 0 * inf never produces NaN in slab tests."""
    return 1.0 / np.where(np.abs(x) < 1e-12, np.float32(1e-12), x)


@dataclass(frozen=True, eq=False)
class Box:
    """Oriented box with `half` (3,) half extents along its local axes.

    inside=True makes it an inside-out box (a room seen from within): rays hit
    the far face and normals point inwards.
    """

    centre: np.ndarray
    half: np.ndarray
    R: np.ndarray
    inside: bool = False

    @property
    def bounding_radius(self) -> float:
        return np.inf if self.inside else float(np.linalg.norm(self.half))

    @property
    def extent(self) -> np.ndarray:
        return np.abs(self.R) @ self.half

    def intersect(self, o: np.ndarray, d: np.ndarray) -> Hit:
        ol, dl = _to_local(o, d, self.centre, self.R)
        t_near = t_far = None
        ax_near = np.zeros(dl.shape[1], dtype=np.int8)
        ax_far = np.zeros(dl.shape[1], dtype=np.int8)
        for k in range(3):
            inv = _safe_inv(dl[k])
            t1, t2 = (-self.half[k] - ol[k]) * inv, (self.half[k] - ol[k]) * inv
            lo, hi = np.minimum(t1, t2), np.maximum(t1, t2)
            if k == 0:
                t_near, t_far = lo, hi
                continue
            ax_near[lo > t_near] = k
            ax_far[hi < t_far] = k
            t_near, t_far = np.maximum(t_near, lo), np.minimum(t_far, hi)
        t, axis = (t_far, ax_far) if self.inside else (t_near, ax_near)
        ok = (t_near <= t_far) & (t > _EPS)
        # The entry face of a solid box and the exit face of a room both face against the ray.
        n_local = np.zeros_like(dl)
        cols = np.arange(dl.shape[1])
        n_local[axis, cols] = -np.sign(dl[axis, cols])
        return Hit(np.where(ok, t, np.inf), linear(self.R, n_local))

    def sdf(self, p: np.ndarray) -> np.ndarray:
        """(N,) signed distance of points (3, N) to the solid (negative inside); room: distance to the walls."""
        q = np.abs(linear(self.R.T, p - self.centre[:, None])) - self.half[:, None]
        out = np.linalg.norm(np.maximum(q, 0.0), axis=0) + np.minimum(q.max(0), 0.0)
        return -out if self.inside else out


@dataclass(frozen=True, eq=False)
class Sphere:
    centre: np.ndarray
    radius: float

    @property
    def bounding_radius(self) -> float:
        return float(self.radius)

    @property
    def extent(self) -> np.ndarray:
        return np.full(3, float(self.radius))

    def intersect(self, o: np.ndarray, d: np.ndarray) -> Hit:
        oc = (np.reshape(o, (3, -1)) - self.centre[:, None]).astype(d.dtype)
        b = (oc * d).sum(0)
        c = (oc * oc).sum(0) - self.radius**2
        disc = b * b - c
        t = -b - np.sqrt(np.maximum(disc, 0.0))
        ok = (disc >= 0) & (t > _EPS)
        t = np.where(ok, t, np.inf)
        p = oc + d * np.where(ok, t, 0.0)
        return Hit(t, p / self.radius)

    def sdf(self, p: np.ndarray) -> np.ndarray:
        return np.linalg.norm(p - self.centre[:, None], axis=0) - self.radius


@dataclass(frozen=True, eq=False)
class Cylinder:
    """Capped cylinder along its local z axis: `radius`, `half_height` (metres)."""

    centre: np.ndarray
    radius: float
    half_height: float
    R: np.ndarray

    @property
    def bounding_radius(self) -> float:
        return float(np.hypot(self.radius, self.half_height))

    @property
    def extent(self) -> np.ndarray:
        return np.abs(self.R) @ np.array([self.radius, self.radius, self.half_height])

    def intersect(self, o: np.ndarray, d: np.ndarray) -> Hit:
        ol, dl = _to_local(o, d, self.centre, self.R)
        (ox, oy, oz), (dx, dy, dz) = ol, dl
        r, hh = self.radius, self.half_height
        # Side: entry root of |xy(t)|^2 = r^2, valid within the height range.
        a = dx * dx + dy * dy
        b = ox * dx + oy * dy
        disc = b * b - a * (ox * ox + oy * oy - r * r)
        t_side = (-b - np.sqrt(np.maximum(disc, 0.0))) / np.maximum(a, 1e-12)
        ok_side = (disc >= 0) & (a > 1e-12) & (t_side > _EPS) & (np.abs(oz + t_side * dz) <= hh)
        # Cap: the plane facing the ray, valid within the radius.
        cap_sign = -np.sign(dz)
        t_cap = (cap_sign * hh - oz) * _safe_inv(dz)
        xc, yc = ox + t_cap * dx, oy + t_cap * dy
        ok_cap = (t_cap > _EPS) & (xc * xc + yc * yc <= r * r) & (dz != 0)
        t_side = np.where(ok_side, t_side, np.inf)
        t_cap = np.where(ok_cap, t_cap, np.inf)
        use_side = t_side <= t_cap
        t = np.minimum(t_side, t_cap)
        ts = np.where(np.isfinite(t), t, 0.0)
        zero = np.zeros_like(t)
        n_local = np.where(use_side, np.stack([(ox + ts * dx) / r, (oy + ts * dy) / r, zero]), np.stack([zero, zero, cap_sign]))
        return Hit(t, linear(self.R, n_local))

    def sdf(self, p: np.ndarray) -> np.ndarray:
        pl = linear(self.R.T, p - self.centre[:, None])
        q = np.stack([np.hypot(pl[0], pl[1]) - self.radius, np.abs(pl[2]) - self.half_height])
        return np.linalg.norm(np.maximum(q, 0.0), axis=0) + np.minimum(q.max(0), 0.0)


Primitive = Box | Sphere | Cylinder


def rot_z(yaw: float) -> np.ndarray:
    """(3, 3) rotation by `yaw` radians about the world z (up) axis."""
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
