"""scripts/pack_psb.py: the PSB travels to the GPU machine and back unchanged."""

from __future__ import annotations

import importlib.util

import numpy as np
import pytest

from anseg.datasets import PSB_CATEGORIES
from anseg.study.store import REPO

spec = importlib.util.spec_from_file_location("pack_psb", REPO / "scripts" / "pack_psb.py")
pack_psb = importlib.util.module_from_spec(spec)
spec.loader.exec_module(pack_psb)

TETRAHEDRON = "OFF\n4 4 6\n0.000000 0.000000 0.000000\n1.250000 0.000000 0.000000\n0.000000 -0.333333 0.000000\n" \
              "0.000000 0.000000 2.000001\n3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n"


def _psb_tree(root, trailer=""):
    for category in PSB_CATEGORIES:
        folder = root / "LabeledDB_new" / category
        folder.mkdir(parents=True)
        (folder / "1.off").write_text(TETRAHEDRON + trailer)
        (folder / "1_labels.txt").write_text("a\n1 2\nb\n3 4\n")


def test_pack_then_unpack_gives_back_the_same_files(tmp_path):
    _psb_tree(tmp_path / "in", trailer="<filter name='a MeshLab note'/>\n")
    pack_psb.pack(tmp_path / "in", tmp_path / "psb.tar.xz")
    pack_psb.unpack(tmp_path / "psb.tar.xz", tmp_path / "out")
    for category in PSB_CATEGORIES:
        for name in ("1.off", "1_labels.txt"):
            before = (tmp_path / "in" / "LabeledDB_new" / category / name).read_text()
            assert (tmp_path / "out" / "LabeledDB_new" / category / name).read_text() == before


def test_pack_refuses_coordinates_it_cannot_carry_exactly(tmp_path):
    _psb_tree(tmp_path / "in")
    off = tmp_path / "in" / "LabeledDB_new" / PSB_CATEGORIES[0] / "1.off"
    off.write_text(off.read_text().replace("1.250000", "1.2500001"))  # seven decimals
    with pytest.raises(SystemExit, match="does not survive"):
        pack_psb.pack(tmp_path / "in", tmp_path / "psb.tar.xz")


def test_parse_reads_counts_faces_and_trailer():
    vertices, faces, counts, trailer = pack_psb._parse_off(TETRAHEDRON + "tail\n")
    assert vertices.shape == (4, 3) and faces.shape == (4, 3) and list(counts) == [4, 4, 6] and trailer == "tail\n"
    assert np.isclose(vertices[3, 2], 2.000001)
