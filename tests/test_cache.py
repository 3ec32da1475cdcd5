"""Atomic writes: outputs get the permissions the user's umask gives any new file."""

from __future__ import annotations

import os
import stat

import numpy as np
import pytest
from conftest import grid_mesh

from anseg.cache import atomic_write
from anseg.mesh_files import save_mesh

WRITERS = {
    "labels.txt": lambda tmp: np.savetxt(tmp, np.arange(4), fmt="%d"),
    "mesh.ply": lambda tmp: save_mesh(tmp, grid_mesh(2)),
}


@pytest.mark.parametrize("writer", list(WRITERS))
@pytest.mark.parametrize("umask", [0o022, 0o002, 0o077])
def test_atomic_write_gives_the_mode_of_a_new_file(tmp_path, umask, writer):
    before = os.umask(umask)
    try:
        path = atomic_write(tmp_path / writer, WRITERS[writer])
        after = os.umask(umask)
    finally:
        os.umask(before)
    assert oct(stat.S_IMODE(path.stat().st_mode)) == oct(0o666 & ~umask)  # not mkstemp's 0600
    assert after == umask  # reading the umask put it back
    assert [p.name for p in tmp_path.iterdir()] == [path.name]
