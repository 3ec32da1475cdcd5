"""Pack the 16 PSB categories into a compact archive for the GPU machine, and unpack it there.

The device tool carries at most 64 MiB and the PSB archive is 100 MB, so the
meshes travel as integer arrays: every vertex coordinate in the PSB ``.off``
files has six decimals, so ``round(x * 1e6)`` is exact; ``pack`` checks that
the unpacked text parses to the very same float64 values as the original,
mesh by mesh, and refuses otherwise. Label files travel as they are.

    python scripts/pack_psb.py pack <data root holding psb_labeled.tar.gz> <out.tar.xz>
    python scripts/pack_psb.py unpack <in.tar.xz> <data root to create>

The unpacked root holds ``LabeledDB_new/<Category>/`` as the distribution
lays it out, which :mod:`anseg.datasets.psb` reads like the archive. This is
a transport format for our own runs, not a way to redistribute the data.
"""

from __future__ import annotations

import anseg  # noqa: F401  first: importing anseg pins the float kernels before NumPy and torch load

# isort: split
import io
import sys
import tarfile
from pathlib import Path

import numpy as np

from anseg.datasets.psb import PSB_CATEGORIES

FOLDER = "LabeledDB_new"
SCALE = 10**6


def _parse_off(text: str) -> tuple[np.ndarray, np.ndarray, np.ndarray, str]:
    """Vertices, faces, the header's three counts and the text after the faces (some files carry a MeshLab note)."""
    lines = text.splitlines(keepends=True)
    if lines[0].strip() != "OFF":
        raise ValueError("not an OFF file with its counts on the second line")
    counts = np.array(lines[1].split(), dtype=np.int64)
    n_vertices, n_faces = int(counts[0]), int(counts[1])
    vertices = np.array(" ".join(lines[2:2 + n_vertices]).split(), dtype=np.float64).reshape(n_vertices, 3)
    faces = np.array(" ".join(lines[2 + n_vertices:2 + n_vertices + n_faces]).split(), dtype=np.int64).reshape(n_faces, 4)
    if (faces[:, 0] != 3).any():
        raise ValueError("not a triangle mesh")
    return vertices, faces[:, 1:].astype(np.int32), counts, "".join(lines[2 + n_vertices + n_faces:])


def _off_text(vertices_int: np.ndarray, faces: np.ndarray, counts: np.ndarray, trailer: str) -> str:
    lines = ["OFF", " ".join(str(c) for c in counts)]
    lines += [" ".join(f"{v / SCALE:.6f}" for v in row) for row in vertices_int]
    lines += [f"3 {a} {b} {c}" for a, b, c in faces]
    return "\n".join(lines) + "\n" + trailer


def pack(root: Path, out: Path) -> None:
    from anseg.datasets.archive import dataset_folder

    source = dataset_folder(root, FOLDER, "psb_labeled.tar.gz")
    with tarfile.open(out, "w:xz", preset=9) as tar:
        for category in PSB_CATEGORIES:
            arrays = {}
            for off in sorted((source / category).glob("*.off")):
                vertices, faces, counts, trailer = _parse_off(off.read_text())
                as_int = np.round(vertices * SCALE).astype(np.int32)
                again = _parse_off(_off_text(as_int, faces, counts, trailer))
                if not (np.array_equal(again[0], vertices) and np.array_equal(again[1], faces) and again[3] == trailer):
                    raise SystemExit(f"{off}: the mesh does not survive the packing exactly; not packed")
                arrays[f"{off.stem}_v"], arrays[f"{off.stem}_f"] = as_int, faces
                arrays[f"{off.stem}_c"] = counts
                arrays[f"{off.stem}_t"] = np.frombuffer(trailer.encode(), dtype=np.uint8)
                tar.add(off.with_name(f"{off.stem}_labels.txt"), f"{FOLDER}/{category}/{off.stem}_labels.txt")
            buffer = io.BytesIO()
            np.savez(buffer, **arrays)
            info = tarfile.TarInfo(f"{category}.npz")
            info.size = buffer.tell()
            buffer.seek(0)
            tar.addfile(info, buffer)
            print(f"packed {category}: {len(arrays) // 4} meshes", flush=True)


def unpack(archive: Path, root: Path) -> None:
    with tarfile.open(archive, "r:xz") as tar:
        tar.extractall(root, filter="data")
    for category in PSB_CATEGORIES:
        packed = root / f"{category}.npz"
        with np.load(packed) as arrays:
            for name in sorted(k[:-2] for k in arrays.files if k.endswith("_v")):
                trailer = arrays[f"{name}_t"].tobytes().decode()
                text = _off_text(arrays[f"{name}_v"], arrays[f"{name}_f"], arrays[f"{name}_c"], trailer)
                (root / FOLDER / category / f"{name}.off").write_text(text)
        packed.unlink()
    print(f"unpacked {len(PSB_CATEGORIES)} categories into {root / FOLDER}")


if __name__ == "__main__":
    if len(sys.argv) != 4 or sys.argv[1] not in ("pack", "unpack"):
        raise SystemExit(__doc__)
    (pack if sys.argv[1] == "pack" else unpack)(Path(sys.argv[2]), Path(sys.argv[3]))
