"""anseg: 3D shape segmentation via attentive nonuniform downsampling."""

# first, before NumPy, numba and torch load: one choice of float kernels on every x86-64 CPU (anseg.kernels says why)
from anseg import kernels

kernels.pin()

from anseg.mesh import Mesh, MeshError, repair  # noqa: E402
from anseg.mesh_files import load_mesh, save_mesh  # noqa: E402

__all__ = ["Mesh", "MeshError", "load_mesh", "repair", "save_mesh"]
__version__ = "0.1.0"
