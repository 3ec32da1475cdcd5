"""Fuzzing the mesh readers: damaged OFF, OBJ, PLY, STL and GLB files give a MeshError or a valid mesh, nothing else."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import grid_mesh
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from anseg.mesh import Mesh, MeshError
from anseg.mesh_files import load_mesh, save_mesh

# file name -> trimesh's exporter, or None for save_mesh
FORMATS = {"mesh.off": None, "mesh.obj": None, "mesh.ply": None, "binary.stl": "stl", "ascii.stl": "stl_ascii", "mesh.glb": "glb"}


@pytest.fixture(scope="module")
def originals(tmp_path_factory):
    import trimesh

    folder = tmp_path_factory.mktemp("originals")
    mesh = grid_mesh(3, closed=True)
    out = {}
    for name, file_type in FORMATS.items():
        path = folder / name
        if file_type is None:
            save_mesh(path, mesh)
        else:
            trimesh.Trimesh(mesh.vertices, mesh.faces, process=False).export(path, file_type=file_type)
        out[name] = path.read_bytes()
    return out


mutations = st.one_of(
    st.tuples(st.just("truncate"), st.floats(0, 1)),
    st.tuples(st.just("flip"), st.lists(st.tuples(st.floats(0, 1), st.integers(0, 255)), min_size=1, max_size=8)),
    st.tuples(st.just("insert"), st.tuples(st.floats(0, 1), st.binary(min_size=1, max_size=16))),
)


def mutate(data: bytes, mutation) -> bytes:
    kind, spec = mutation
    if kind == "truncate":
        return data[: int(spec * len(data))]
    if kind == "flip":
        out = bytearray(data)
        for where, value in spec:
            out[min(int(where * len(out)), len(out) - 1)] = value
        return bytes(out)
    where, chunk = spec
    cut = int(where * len(data))
    return data[:cut] + chunk + data[cut:]


@pytest.mark.filterwarnings("error::RuntimeWarning")  # an overflow on the way is a failure, not a warning
@settings(max_examples=400, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(name=st.sampled_from(list(FORMATS)), mutation=mutations)
def test_damaged_files_give_a_mesh_error_or_a_valid_mesh(tmp_path, originals, name, mutation):
    path = tmp_path / f"damaged-{name}"
    path.write_bytes(mutate(originals[name], mutation))
    try:
        mesh = load_mesh(path)
    except MeshError:
        return
    assert isinstance(mesh, Mesh) and mesh.n_faces > 0 and np.isfinite(mesh.vertices).all()


@pytest.mark.parametrize("text, suffix", [
    ("OFF\n1000000000 2000000000 0\n0 0 0\n", ".off"),
    ("ply\nformat ascii 1.0\nelement vertex 1000000000\nproperty float x\nproperty float y\nproperty float z\n"
     "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n", ".ply"),
    ("ply\nformat binary_little_endian 1.0\nelement vertex 300000000\nproperty float x\nproperty float y\n"
     "property float z\nend_header\n", ".ply"),
])
def test_a_header_promising_a_billion_elements_is_refused_before_reading(tmp_path, text, suffix):
    path = tmp_path / f"huge{suffix}"
    path.write_text(text)
    with pytest.raises(MeshError, match="more than its"):
        load_mesh(path)
