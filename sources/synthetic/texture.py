"""Procedural solid textures: colour as a function of world position only.

Because the colour depends only on the 3D point (never on the view), every
view of a surface point sees the same colour: photometric consistency holds
exactly. Patterns mix value noise, random sinusoids and a soft 3D checker, with
the finest features a few centimetres wide (trackable at 320x240, mild aliasing).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sources.synthetic.primitives import linear

_TABLE = 1024  # value-noise lattice hash table size (power of two)


@dataclass(frozen=True, eq=False)
class SolidTexture:
    """A seeded solid texture with a base colour.

    base: (3,) RGB in [0, 1]. dirs: (K, 3) unit wave directions; freqs: (K,)
    angular frequencies in rad/m; phases: (K,) radians; tint_phases: (K, 3) per-channel
    phases for a faint colour variation. checker: cell size in metres.
    noise_cell: value-noise lattice spacing in metres. values: (_TABLE,) lattice values in [0, 1].
    """

    base: np.ndarray
    dirs: np.ndarray
    freqs: np.ndarray
    phases: np.ndarray
    tint_phases: np.ndarray
    checker: float
    noise_cell: float
    values: np.ndarray
    contrast: float = 0.5

    def __call__(self, p: np.ndarray) -> np.ndarray:
        """(3, N) world points (metres) -> (3, N) float32 RGB in [0, 1]."""
        p = p.astype(np.float32)
        # float32 throughout: numpy's float32 sin is vectorised and ~10x faster than float64.
        arg = linear(self.dirs * self.freqs[:, None], p) + self.phases[:, None].astype(np.float32)
        waves = np.sin(arg).mean(0) * 2.0
        q = p / np.float32(self.noise_cell)
        noise = (value_noise(q, self.values) + 0.5 * value_noise(2.0 * q + 17.0, self.values)) / 0.75 - 1.0
        sx, sy, sz = np.sin(np.float32(np.pi / self.checker) * p)
        check = np.tanh(6.0 * sx * sy * sz)
        g = np.clip(0.35 * waves + 0.4 * noise + 0.35 * check, -1.0, 1.0)
        # Faint per-channel colour variation from phase-shifted copies of the first waves.
        tint = np.sin(arg[:3, None, :] + self.tint_phases[:3, :, None].astype(np.float32)).mean(0)  # (3, N)
        rgb = self.base[:, None].astype(np.float32) * (1.0 + np.float32(self.contrast) * g) + 0.08 * tint
        return np.clip(rgb, 0.0, 1.0).astype(np.float32)


_PRIMES = (np.int32(73856093), np.int32(19349663), np.int32(83492791))


def _mix(h: np.ndarray) -> np.ndarray:
    """Scramble an int32 lattice hash (wrapping arithmetic) -> index into the value table."""
    h = h ^ (h >> 13)
    return ((h * np.int32(1274126177)) >> 7) & (_TABLE - 1)


def value_noise(q: np.ndarray, values: np.ndarray) -> np.ndarray:
    """(3, N) lattice-unit coordinates -> (N,) smooth noise in [0, 1] (trilinear, smoothstep weights)."""
    i = np.floor(q)
    f = q - i
    w = f * f * (3.0 - 2.0 * f)
    i = i.astype(np.int32)
    # Per-axis hash terms of the two lattice neighbours, combined by xor at each corner.
    h = [(i[k] * _PRIMES[k], (i[k] + 1) * _PRIMES[k]) for k in range(3)]
    wk = [(1.0 - w[k], w[k]) for k in range(3)]
    vals = values.astype(np.float32)
    out = np.zeros(q.shape[1], dtype=np.float32)
    for a in (0, 1):
        for b in (0, 1):
            hab, wab = h[0][a] ^ h[1][b], wk[0][a] * wk[1][b]
            for c in (0, 1):
                out += (wab * wk[2][c]) * np.take(vals, _mix(hab ^ h[2][c]))
    return out


def random_texture(rng: np.random.Generator, base: np.ndarray, feature: float, n_waves: int = 6) -> SolidTexture:
    """A seeded texture whose finest features are about `feature` metres wide."""
    dirs = rng.normal(size=(n_waves, 3))
    dirs /= np.linalg.norm(dirs, axis=-1, keepdims=True)
    # Wavelengths between 2x and 6x the feature size.
    freqs = 2 * np.pi / (feature * rng.uniform(2.0, 6.0, n_waves))
    return SolidTexture(
        base=np.asarray(base, dtype=np.float64),
        dirs=dirs,
        freqs=freqs,
        phases=rng.uniform(0, 2 * np.pi, n_waves),
        tint_phases=rng.uniform(0, 2 * np.pi, (n_waves, 3)),
        checker=feature * rng.uniform(3.0, 5.0),
        noise_cell=feature * rng.uniform(1.5, 2.5),
        values=rng.uniform(0.0, 1.0, _TABLE),
    )


def random_colour(rng: np.random.Generator, lo: float = 0.25, hi: float = 0.75) -> np.ndarray:
    """(3,) a mid-range RGB base colour, leaving headroom for texture contrast."""
    return rng.uniform(lo, hi, 3)


@dataclass(frozen=True, eq=False)
class RoomTexture:
    """Floor / wall / ceiling textures of an axis-aligned room, chosen by height alone.

    Points within `tol` metres of `z_floor` use `floor`, near `z_ceiling` use `ceiling`,
    all others `walls`: still a function of position only (view-independent).
    """

    floor: SolidTexture
    walls: SolidTexture
    ceiling: SolidTexture
    z_floor: float
    z_ceiling: float
    tol: float = 1e-4

    def __call__(self, p: np.ndarray) -> np.ndarray:
        """(3, N) world points -> (3, N) float32 RGB in [0, 1]."""
        floor = p[2] < self.z_floor + self.tol
        ceiling = p[2] > self.z_ceiling - self.tol
        out = np.empty((3, p.shape[1]), dtype=np.float32)
        for tex, m in ((self.floor, floor), (self.ceiling, ceiling), (self.walls, ~(floor | ceiling))):
            if m.any():
                out[:, m] = tex(p[:, m])
        return out


@dataclass(frozen=True, eq=False)
class SkyGradient:
    """Colour of rays that hit nothing, from their world direction alone (infinitely far, world z up).

    `horizon` (3,) RGB at and below the horizon, blending to `zenith` (3,) RGB straight up.
    """

    horizon: np.ndarray
    zenith: np.ndarray

    def __call__(self, d: np.ndarray) -> np.ndarray:
        """(3, N) unit world directions -> (3, N) float32 RGB in [0, 1]."""
        s = np.sqrt(np.clip(d[2], 0.0, 1.0))
        return ((1.0 - s) * self.horizon[:, None] + s * self.zenith[:, None]).astype(np.float32)
