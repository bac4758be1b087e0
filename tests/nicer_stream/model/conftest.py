"""Fixtures for the model tests."""
from __future__ import annotations

import numpy as np
import pytest


@pytest.fixture
def frustum_points():
    """frustum_points(seed, n=5000) -> (n, 3): points a camera at the origin looking along +z
    sees, z in [1, 5], a widening cone (the first frame a scene bound is chosen from)."""
    def make(seed: int, n: int = 5000) -> np.ndarray:
        rng = np.random.default_rng(seed)
        z = rng.uniform(1, 5, n)
        return np.stack([rng.uniform(-0.5, 0.5, n) * z, rng.uniform(-0.4, 0.4, n) * z, z], 1)

    return make
