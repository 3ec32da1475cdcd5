"""anseg.geometry.geodesic: the farthest-point sources and their areas (the AGD on shapes: test_features)."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from anseg.geometry import geodesic


@settings(max_examples=40, deadline=None)
@given(points=arrays(np.float64, st.tuples(st.integers(1, 40), st.just(3)), elements=st.floats(-10, 10)),
       n=st.integers(1, 12), data=st.data())
def test_farthest_point_sources_share_out_the_whole_area(points, n, data):
    area = data.draw(arrays(np.float64, len(points), elements=st.floats(0.1, 5.0)))
    sources, weights = geodesic.farthest_point_sources(points, area, n)
    assert 1 <= len(sources) <= n and len(set(sources.tolist())) == len(sources)
    assert len(weights) == len(sources) and np.isclose(weights.sum(), area.sum())
    centre = (points * area[:, None]).sum(axis=0) / area.sum()
    distance = np.linalg.norm(points - centre, axis=1)
    assert distance[sources[0]] == distance.max()  # the first source: the point farthest from the area centroid
