"""Procedural outdoor scene `street`: a straight street with facades, roadside objects and open sky.

World frame: z up, metres, road surface at z = 0; the street runs along +x with
the road at |y| < 4 m, kerbed sidewalks up to |y| = 6.5 m and building facades
from there (some set back). Rays that hit nothing see a sky gradient with depth 0.
The camera drives along the street ~1.5 m above the road, looking ahead. Measured
at 320x240 (seed 0): depths from 2.6 m (road at the bottom of the image), median
~10 m, 95 % below ~55 m; ~2-3 % of the pixels, near the vanishing point, see the
far part of the street (up to ~330 m). ~10-15 % of the pixels are sky.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from nicer_stream.errors import SourceError
from sources.synthetic.primitives import Box, Cylinder, Sphere, rot_z
from sources.synthetic.render import Surface, random_light
from sources.synthetic.scene import SyntheticScene
from sources.synthetic.texture import SkyGradient, random_colour, random_texture
from sources.synthetic.trajectory import DOWN, look_at

STEP = 1.0
"""Camera advance along the street per frame (metres)."""
MAX_FRAMES = 250
"""Longest sequence: the street has buildings up to LOOK_AHEAD metres beyond the last camera."""
LOOK_AHEAD = 60.0
ROAD_HALF, FACADE_Y, KERB = 4.0, 6.5, 0.15
"""Road half width, distance of the front building line from the street axis, sidewalk height (metres)."""
X_START, X_END = -30.0, (MAX_FRAMES - 1) * STEP + LOOK_AHEAD + 10.0
"""Extent of the buildings along x (the first camera is at x = 0)."""
SKY = SkyGradient(horizon=np.array([0.82, 0.88, 0.95]), zenith=np.array([0.35, 0.55, 0.85]))


@dataclass(frozen=True)
class StreetPath:
    """Camera poses along the street: frame i is at x = i * step (exactly `step` metres per frame; the
    lateral wiggle adds < 1 %), so N frames cover (N - 1) * step metres and `poses(N)` is a prefix of
    `poses(M)` for N < M (unlike the room's orbit, which spans the same arc for any N).

    The camera sways sideways (`lateral_amp` metres, period `lateral_period` frames) and yaws
    (`yaw_amp` radians, period `yaw_period` frames), looking `pitch` radians below the horizon.
    """

    step: float
    height: float
    pitch: float
    lateral_amp: float
    lateral_period: float
    yaw_amp: float
    yaw_period: float
    phases: tuple[float, float]
    max_frames: int = MAX_FRAMES

    def __call__(self, n_frames: int) -> np.ndarray:
        """(N, 4, 4) float64 T_world_cam of frames 0..N-1."""
        if not 1 <= n_frames <= self.max_frames:
            raise SourceError(
                f"synthetic street: {n_frames} frames would drive past the street's end: give frames in [1, {self.max_frames}]"
            )
        i = np.arange(n_frames, dtype=np.float64)
        y = self.lateral_amp * np.sin(2 * np.pi * i / self.lateral_period + self.phases[0])
        eye = np.stack([i * self.step, y, np.full_like(i, self.height)], -1)
        yaw = self.yaw_amp * np.sin(2 * np.pi * i / self.yaw_period + self.phases[1])
        c = np.cos(self.pitch)
        ahead = np.stack([c * np.cos(yaw), c * np.sin(yaw), np.full_like(i, -np.sin(self.pitch))], -1)
        return np.stack([look_at(e, e + a, DOWN) for e, a in zip(eye, ahead)])


def _slab(x0: float, x1: float, y0: float, y1: float, z0: float, z1: float) -> Box:
    """Axis-aligned box spanning [x0, x1] x [y0, y1] x [z0, z1]."""
    lo, hi = np.array([x0, y0, z0]), np.array([x1, y1, z1])
    return Box((lo + hi) / 2, (hi - lo) / 2, np.eye(3))


def _ground(rng: np.random.Generator) -> list[Surface]:
    """The road (a slab whose top is z = 0, reaching behind the buildings) and two kerbed sidewalks."""
    grey = rng.uniform(0.3, 0.45) + rng.uniform(-0.03, 0.03, 3)
    road = Surface(_slab(X_START - 10, X_END + 20, -30, 30, -1.0, 0.0), random_texture(rng, grey, 0.08), "road")
    paving = random_texture(rng, random_colour(rng, 0.5, 0.7), 0.1)
    walks = [
        Surface(_slab(X_START - 10, X_END + 20, *sorted((s * ROAD_HALF, s * FACADE_Y)), 0.0, KERB), paving, f"sidewalk{k}")
        for k, s in enumerate((-1, 1))
    ]
    return [road, *walks]


def _buildings(rng: np.random.Generator, side: int) -> list[Surface]:
    """Boxes along one side (side = +-1 for +-y), varied widths, heights and textures, some set back."""
    out, x = [], X_START
    while x < X_END:
        width, depth, height = rng.uniform(8, 22), rng.uniform(8, 14), rng.uniform(5, 18)
        front = FACADE_Y + (rng.uniform(1.0, 4.0) if rng.random() < 0.35 else 0.0)
        box = _slab(x, x + width, *sorted((side * front, side * (front + depth))), 0.0, height)
        tex = random_texture(rng, random_colour(rng, 0.3, 0.8), rng.uniform(0.15, 0.35))
        out.append(Surface(box, tex, f"building{len(out)}{'LR'[side > 0]}"))
        x += width + (rng.uniform(2.0, 5.0) if rng.random() < 0.3 else 0.0)
    return out


_CYLINDERS = {"pole": ((0.08, 0.14), (3.0, 6.0)), "tree": ((0.15, 0.25), (2.5, 3.5)), "bollard": ((0.1, 0.15), (0.7, 1.0))}
"""Radius and height ranges (metres) of the cylindrical roadside objects."""


def _roadside(rng: np.random.Generator, side: int) -> list[Surface]:
    """Poles, trees (trunk + crown), boxes and bollards standing on one sidewalk."""
    out, x = [], X_START + 5
    while x < X_END:
        kind = rng.choice(["pole", "tree", "box", "bollard"], p=[0.4, 0.1, 0.35, 0.15])
        tex = random_texture(rng, random_colour(rng, 0.2, 0.8), rng.uniform(0.03, 0.06))
        y = side * rng.uniform(4.4, 4.8)
        if kind == "box":
            half = np.array([rng.uniform(0.3, 0.7), rng.uniform(0.3, 0.6), rng.uniform(0.4, 0.8)])
            shapes = [Box(np.array([x, side * 5.5, KERB + half[2]]), half, rot_z(rng.uniform(-0.3, 0.3)))]
        else:
            r, h = (rng.uniform(*limits) for limits in _CYLINDERS[kind])
            shapes = [Cylinder(np.array([x, y, KERB + h / 2]), r, h / 2, np.eye(3))]
            if kind == "tree":
                crown = rng.uniform(1.0, 1.5)
                shapes.append(Sphere(np.array([x, y, KERB + h + 0.7 * crown]), crown))
        out += [Surface(s, tex, f"{kind}{len(out)}{'LR'[side > 0]}") for s in shapes]
        x += rng.uniform(8, 16)
    return out


def street_scene(rng: np.random.Generator, seed: int) -> SyntheticScene:
    surfaces = _ground(rng)
    for side in (-1, 1):
        surfaces += _buildings(rng, side) + _roadside(rng, side)
    path = StreetPath(
        step=STEP,
        height=1.5 + rng.uniform(-0.05, 0.05),
        pitch=np.deg2rad(rng.uniform(2.0, 4.0)),
        lateral_amp=rng.uniform(0.3, 0.6),
        lateral_period=rng.uniform(40, 70),
        yaw_amp=np.deg2rad(rng.uniform(2.0, 4.0)),
        yaw_period=rng.uniform(30, 60),
        phases=tuple(rng.uniform(0, 2 * np.pi, 2)),
    )
    return SyntheticScene("street", seed, surfaces, random_light(rng), path, sky=SKY, mesh_edge=1.0)
