"""Procedural indoor scenes: a closed room with textured objects, deterministic per seed.

World frame: z up, metres, floor at z = 0. Poses are `T_world_cam` with OpenCV
camera axes. Scenes: `room` (~4 x 3 x 2.6 m, objects on the floor) and
`tabletop` (3 x 3 x 2.4 m, objects on a table, camera closer). The camera orbits
the objects; `trajectory(N)` samples the same arc for any N (more frames: smaller steps).
"""
from __future__ import annotations

from functools import partial

import numpy as np

from sources.synthetic.primitives import Box, Cylinder, Sphere, rot_z
from sources.synthetic.render import Surface, random_light
from sources.synthetic.scene import SyntheticScene
from sources.synthetic.texture import RoomTexture, random_colour, random_texture
from sources.synthetic.trajectory import OrbitParams, orbit_trajectory


def _room_surface(rng: np.random.Generator, half: np.ndarray, feature: float) -> Surface:
    """Inside-out room box standing on z = 0 with distinct floor, wall and ceiling textures."""
    tex = RoomTexture(
        floor=random_texture(rng, random_colour(rng), feature),
        walls=random_texture(rng, random_colour(rng, 0.4, 0.7), 1.5 * feature),
        ceiling=random_texture(rng, random_colour(rng, 0.5, 0.7), 2.0 * feature),
        z_floor=0.0,
        z_ceiling=2 * half[2],
    )
    box = Box(centre=np.array([0.0, 0.0, half[2]]), half=np.asarray(half, float), R=np.eye(3), inside=True)
    return Surface(box, tex, "room")


def _place(rng: np.random.Generator, radii: list[float], lo: np.ndarray, hi: np.ndarray, gap: float) -> np.ndarray:
    """(K, 2) xy positions in the rectangle [lo, hi] whose footprint discs (radii) are `gap` apart."""
    for _ in range(1000):
        xy = rng.uniform(lo, hi, (len(radii), 2))
        r = np.asarray(radii)
        dist = np.linalg.norm(xy[:, None] - xy[None], axis=-1) + np.eye(len(r)) * 1e9
        if (dist > r[:, None] + r[None] + gap).all():
            return xy
    raise RuntimeError("could not place objects without overlap; enlarge the region")


def _objects(rng, z0: float, lo, hi, size: float, feature: float) -> list[Surface]:
    """Two boxes, two spheres (one resting on the first box) and a cylinder standing on z = z0.

    `size` scales all objects (1.0 = room scale, about 0.5 m objects).
    """
    box_a = np.array([rng.uniform(0.2, 0.35), rng.uniform(0.2, 0.35), rng.uniform(0.2, 0.35)]) * size
    box_b = np.array([rng.uniform(0.12, 0.2), rng.uniform(0.12, 0.2), rng.uniform(0.1, 0.2)]) * size
    r_sphere = rng.uniform(0.18, 0.28) * size
    r_top = rng.uniform(0.1, 0.16) * size
    r_cyl, hh_cyl = rng.uniform(0.1, 0.16) * size, rng.uniform(0.3, 0.45) * size
    xy = _place(rng, [np.linalg.norm(box_a[:2]), np.linalg.norm(box_b[:2]), r_sphere, r_cyl], lo, hi, 0.1 * size)

    def tex():
        return random_texture(rng, random_colour(rng, 0.2, 0.8), feature * rng.uniform(0.8, 1.2))

    def at(k: int, z: float) -> np.ndarray:
        return np.array([xy[k, 0], xy[k, 1], z])

    return [
        Surface(Box(at(0, z0 + box_a[2]), box_a, rot_z(rng.uniform(0, np.pi))), tex(), "box_a"),
        Surface(Box(at(1, z0 + box_b[2]), box_b, rot_z(rng.uniform(0, np.pi))), tex(), "box_b"),
        Surface(Sphere(at(2, z0 + r_sphere), r_sphere), tex(), "sphere_a"),
        Surface(Sphere(at(0, z0 + 2 * box_a[2] + r_top), r_top), tex(), "sphere_b"),
        Surface(Cylinder(at(3, z0 + hh_cyl), r_cyl, hh_cyl, np.eye(3)), tex(), "cylinder"),
    ]


def _orbit(rng, radii, height: float, target: np.ndarray, target_amp: np.ndarray) -> OrbitParams:
    return OrbitParams(
        centre=rng.uniform(-0.05, 0.05, 2),
        radii=np.asarray(radii, float),
        phase0=rng.uniform(0, 2 * np.pi),
        sweep=rng.choice([-1.0, 1.0]) * np.deg2rad(rng.uniform(110, 150)),
        height=height + rng.uniform(-0.05, 0.05),
        height_amp=0.08,
        target=target + rng.uniform(-0.1, 0.1, 3) * target_amp,
        target_amp=np.asarray(target_amp, float),
        wobble=rng.uniform(1.0, 2.0),
    )


def room_scene(rng: np.random.Generator, seed: int) -> SyntheticScene:
    room = _room_surface(rng, np.array([2.0, 1.5, 1.3]), 0.06)
    objs = _objects(rng, 0.0, np.array([-0.95, -0.6]), np.array([0.95, 0.6]), 1.0, 0.04)
    orbit = _orbit(rng, (1.5, 1.05), 1.45, np.array([0.0, 0.0, 0.45]), np.array([0.3, 0.2, 0.1]))
    return SyntheticScene("room", seed, [room, *objs], random_light(rng), partial(orbit_trajectory, orbit))


def tabletop_scene(rng: np.random.Generator, seed: int) -> SyntheticScene:
    room = _room_surface(rng, np.array([1.5, 1.5, 1.2]), 0.05)
    table_half = np.array([0.55, 0.4, 0.36])
    table = Surface(Box(np.array([0.0, 0.0, 0.36]), table_half, np.eye(3)), random_texture(rng, random_colour(rng), 0.03), "table")
    objs = _objects(rng, 2 * table_half[2], np.array([-0.33, -0.2]), np.array([0.33, 0.2]), 0.4, 0.02)
    orbit = _orbit(rng, (0.85, 0.7), 1.15, np.array([0.0, 0.0, 0.82]), np.array([0.12, 0.08, 0.05]))
    return SyntheticScene("tabletop", seed, [room, table, *objs], random_light(rng), partial(orbit_trajectory, orbit))
