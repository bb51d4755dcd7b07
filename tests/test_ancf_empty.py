"""The empty element set (`ancf.empty_elements`, a belt whose spans are all springs) against what it
replaces: `ancf.subset` of a made one-element set to no index. Every table must agree in shape, dtype and
flags (numba types the kernels' arguments by dtype, dimension, layout and writability)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from beltdyn.model import ancf


@pytest.mark.parametrize("curvature", ancf.CURVATURE_MODELS)
@pytest.mark.parametrize("n_gauss", [2, 3, 5, 7])
@pytest.mark.parametrize("axial_law", ["green-lagrange", "linear"])
def test_empty_elements_equal_the_subset_of_a_made_set(curvature: str, n_gauss: int, axial_law: str) -> None:
    made = ancf.make_elements(np.ones(1), 1.2e5, 0.3, 0.1, curvature=curvature, n_gauss=n_gauss, axial_law=axial_law)
    want = ancf.subset(made, np.zeros(0, dtype=np.int64))
    got = ancf.empty_elements(curvature=curvature, n_gauss=n_gauss, axial_law=axial_law)
    assert got.n_elem == 0
    for f in dataclasses.fields(ancf.ElementSet):
        a, b = getattr(got, f.name), getattr(want, f.name)
        if isinstance(b, np.ndarray):
            assert isinstance(a, np.ndarray), f.name
            assert (a.shape, a.dtype) == (b.shape, b.dtype), f.name
            assert (a.flags.writeable, a.flags.c_contiguous) == (b.flags.writeable, b.flags.c_contiguous), f.name
            np.testing.assert_array_equal(a, b, err_msg=f.name)
        else:
            assert a == b, f.name
