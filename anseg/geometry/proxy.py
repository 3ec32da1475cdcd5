"""Large meshes: the collapse that stands in for them when global quantities are computed.

Above :data:`LARGE_MESH_FACES` faces (scans, CAD; the largest benchmark mesh
has 55,644) the smooth global quantities, the AGD, the HKS, the ``smooth``
group's diffusion and the network's eigenbasis, are computed on one uniform
collapse of the mesh to :data:`PROXY_FACES` faces (about the size of the
larger benchmark meshes) and carried back face by face: their cost grows
faster than the mesh, and the quantities themselves are smooth.
"""

from __future__ import annotations

import warnings

import numpy as np

from anseg.mesh import Mesh

LARGE_MESH_FACES = 60_000
PROXY_FACES = 50_000


def collapse_to_proxy(mesh: Mesh) -> tuple[Mesh, np.ndarray]:
    """A uniform collapse of ``mesh`` to :data:`PROXY_FACES` faces, and the face each input face became on it."""
    from anseg import collapse

    with warnings.catch_warnings():  # a target missed by a few faces changes nothing here
        warnings.simplefilter("ignore", collapse.CollapseWarning)
        coarse, record = collapse.downsample(mesh, None, ratio=PROXY_FACES / mesh.n_faces, mode="uniform")
    return coarse, record.fine_to_coarse
