"""`geometry.belt_path` (the spans and wraps an iterate of the L0 fit or of an arm's balance evaluates)
against the `Layout` of `compute_layout(check=False)` at the same centres: the same numbers exactly, so
the iterates (and the fitted and predicted positions) are what laying out every iterate in full gave."""

from __future__ import annotations

import numpy as np
import pytest

from beltdyn.model.geometry import belt_path, compute_layout


@pytest.mark.parametrize("n", [2, 3, 5, 7, 8, 11])
def test_belt_path_equals_the_unchecked_layout(n: int) -> None:
    rng = np.random.default_rng(n)
    for _ in range(50):
        phi = np.sort(rng.uniform(0.0, 2.0 * np.pi, n))
        center = np.column_stack([np.cos(phi), np.sin(phi)]) * rng.uniform(0.3, 1.0, (n, 1))
        radius = rng.uniform(0.01, 0.08, n)
        side = np.where(rng.random(n) < 0.3, -1.0, 1.0)
        orientation = int(rng.choice([-1, 1]))
        lay = compute_layout(center, radius, side, tuple(f"P{i}" for i in range(n)), orientation=orientation,
                             check=False)
        path = belt_path(center, radius, side, orientation)
        for name in ("span_angle", "span_length", "arc_length", "span_direction"):
            np.testing.assert_array_equal(getattr(path, name), getattr(lay, name), err_msg=name)
        assert path.belt_length == lay.belt_length
        assert path.n == lay.n
