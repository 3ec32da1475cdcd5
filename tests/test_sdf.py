"""anseg.geometry.sdf: the ray pattern and the robust mean of ray lengths (the casts themselves: test_features, test_rays)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from anseg.geometry import sdf


@settings(max_examples=30, deadline=None)
@given(n_rays=st.integers(1, 64), cone=st.floats(1.0, 179.0))
def test_the_cone_pattern_is_unit_directions_inside_the_cone(n_rays, cone):
    pattern = sdf.cone_pattern(n_rays, cone)
    assert pattern.shape == (n_rays, 3)
    np.testing.assert_allclose(np.linalg.norm(pattern, axis=1), 1.0, rtol=1e-12)
    assert (pattern[:, 2] >= np.cos(np.radians(cone) / 2) - 1e-12).all()


def test_the_robust_mean_drops_outliers_and_gives_open_faces_the_thickest_value():
    lengths = np.array([[1.0, 1.0, 1.0, 1.0, 9.0],          # one far hit: rejected
                        [2.0, np.nan, 2.0, np.nan, 2.0],     # misses are left out
                        [np.nan] * 5])                       # every ray escaped
    got = sdf.robust_ray_mean(lengths, np.ones(5))
    assert got[0] == pytest.approx(1.0) and got[1] == pytest.approx(2.0)
    assert got[2] == got[:2].max()
    assert sdf.robust_ray_mean(np.full((2, 3), np.nan), np.ones(3)).tolist() == [1.0, 1.0]  # nothing hit anywhere
