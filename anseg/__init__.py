"""anseg: 3D shape segmentation via attentive nonuniform downsampling."""

from anseg.mesh import Mesh, MeshError, load_mesh, repair, save_mesh

__all__ = ["Mesh", "MeshError", "load_mesh", "repair", "save_mesh"]
__version__ = "0.1.0"
