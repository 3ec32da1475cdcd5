"""Ray casting: our tree against libigl's, and the edge cases of one triangle."""

from __future__ import annotations

import os
import subprocess
import sys

import numba
import numpy as np
import pytest
from test_features import blob

from anseg.geometry import rays


def test_ray_caster_finds_the_same_first_hits_as_libigl():
    import igl

    mesh = blob()
    rng = np.random.default_rng(1)
    origins = rng.uniform(-0.5, 0.5, size=(2000, 3)) * [1.6, 1.0, 0.7]
    directions = rng.standard_normal((2000, 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    face, t = rays.first_hits(rays.build_bvh(mesh.vertices, mesh.faces), origins, directions)
    tree = igl.AABB()
    tree.init(mesh.vertices, mesh.faces)
    ref_face, ref_t, _ = tree.intersect_ray_first(mesh.vertices, mesh.faces, origins, directions)
    assert (face >= 0).all() and (ref_face >= 0).all()  # every origin is inside the closed blob
    assert (face == ref_face).mean() > 0.999
    np.testing.assert_allclose(t[face == ref_face], ref_t[face == ref_face], rtol=1e-6)  # libigl keeps t in float32


def test_ray_caster_on_a_single_triangle():
    bvh = rays.build_bvh(np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]), np.array([[0, 1, 2]]))
    origins = np.array([[0.2, 0.2, 1.0], [0.2, 0.2, -2.0], [0.9, 0.9, 1.0], [0.2, 0.2, 1.0]])
    directions = np.array([[0.0, 0, -1], [0, 0, 1], [0, 0, -1], [0, 0, 1]])
    face, t = rays.first_hits(bvh, origins, directions)
    np.testing.assert_array_equal(face, [0, 0, -1, -1])
    np.testing.assert_allclose(t[:2], [1.0, 2.0])
    assert np.isinf(t[2:]).all()


def test_casting_rays_leaves_torch_with_the_threads_it_had():
    # A fresh process told to use one thread: numba's OpenMP layer would raise torch's count to numba's (the cores).
    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("numba has one thread on this machine, so it cannot change torch's count")
    script = ("import numpy as np, torch\n"
              "from anseg.geometry import rays\n"
              "torch.ones(64, 64) @ torch.ones(64, 64)\n"  # the network ran before this mesh's features
              "bvh = rays.build_bvh(np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]), np.array([[0, 1, 2]]))\n"
              "rays.first_hits(bvh, np.full((5000, 3), [0.2, 0.2, 1.0]), np.tile([0.0, 0, -1], (5000, 1)))\n"
              "print(torch.get_num_threads())\n")
    env = {**{k: v for k, v in os.environ.items() if k != "NUMBA_NUM_THREADS"}, "OMP_NUM_THREADS": "1"}
    out = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["1"]
