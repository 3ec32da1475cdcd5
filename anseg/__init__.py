"""anseg: 3D shape segmentation via attentive nonuniform downsampling."""

from anseg.mesh import Mesh, MeshError, repair
from anseg.mesh_files import load_mesh, save_mesh

__all__ = ["Mesh", "MeshError", "load_mesh", "repair", "save_mesh"]
__version__ = "0.1.0"
