"""Labels of large meshes: the network on every face against the network on a collapse (anseg.pipeline.NETWORK_FACES).

    ANSEG_DATA=/work/shared/datasets python benchmarks/scale_accuracy.py [--categories Teddy Human Airplane Chair]
        [--faces 300000] [--budgets 60000 30000] [--csv FILE]

Each split-0 test mesh of each category is subdivided (every face split in
four, ``igl.upsample``, which moves no vertex) as many times as brings it
closest to ``--faces`` faces; each child face takes its parent's label, so
the ground truth is the benchmark's own. The category's shipped model
(``anseg models``) segments every mesh with the network on all its faces
(``network_faces=inf``, the code before the limit) and through one collapse
to each of ``--budgets`` faces (``network_faces=B``), and, for reference,
the mesh as the benchmark has it. Accuracy is Eq. 5's unit-area reading
(:func:`anseg.metrics.pooled_accuracy`: the mean of the meshes' area-weighted
accuracies), after the graph cut and before it. Prints one row per mesh, the
mean of each category and of all meshes, and the difference of each budget
from the full network with a paired bootstrap interval over the meshes;
``--csv`` keeps the rows. The features are computed in a temporary cache.
"""

from __future__ import annotations

import anseg  # noqa: F401  first: importing anseg pins the float kernels before NumPy and torch load

# isort: split
import argparse
import math
import os
import tempfile
import time

import numpy as np

from anseg import datasets
from anseg.mesh import Mesh
from anseg.metrics import accuracy
from anseg.pipeline import Segmenter, segment

BOOTSTRAP_SAMPLES = 10_000


def subdivided(item, faces: int) -> tuple[Mesh, np.ndarray, int]:
    """The mesh split in four as many times as brings it closest to ``faces`` faces (in log scale), its labels, the times.

    ``igl.upsample`` writes the four children of face f as faces 4f to 4f + 3;
    checked here by the children's centroids, which lie inside their parent.
    """
    import igl

    times = max(0, round(math.log(faces / item.mesh.n_faces, 4)))
    vertices, triangles = igl.upsample(item.mesh.vertices, item.mesh.faces, times) if times else (item.mesh.vertices,
                                                                                                 item.mesh.faces)
    fine = Mesh(vertices, triangles)
    parent = np.arange(fine.n_faces) // 4**times
    reach = np.linalg.norm(item.mesh.vertices[item.mesh.faces] - item.mesh.face_centroids[:, None], axis=2).max(axis=1)
    if (np.linalg.norm(fine.face_centroids - item.mesh.face_centroids[parent], axis=1) > reach[parent] * (1 + 1e-9)).any():
        raise RuntimeError("igl.upsample no longer writes a face's children after one another")
    return fine, item.labels[parent], times


def interval(differences: np.ndarray, seed: int = 0) -> tuple[float, float]:
    """A 95 % percentile bootstrap interval of the mean of paired per-mesh differences."""
    rng = np.random.default_rng(seed)
    means = differences[rng.integers(0, len(differences), (BOOTSTRAP_SAMPLES, len(differences)))].mean(axis=1)
    return tuple(np.percentile(means, [2.5, 97.5]))


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--categories", nargs="+", default=["Teddy", "Human", "Airplane", "Chair"])
    parser.add_argument("--faces", type=int, default=300_000, help="subdivide each mesh to about this many faces")
    parser.add_argument("--budgets", type=int, nargs="+", default=[60_000, 30_000],
                        help="network_faces values to compare with the full network")
    parser.add_argument("--csv", help="also write one row per mesh to this file")
    args = parser.parse_args(argv)
    os.environ["ANSEG_CACHE"] = tempfile.mkdtemp(prefix="anseg-scale-")  # a few GB of features: not the user's cache
    arms = ["full", *(f"budget {b}" for b in args.budgets)]
    network_faces = {"full": math.inf, **{f"budget {b}": b for b in args.budgets}}
    rows = []
    print(f"{'mesh':<14}{'faces':>9}  {'as given':>9}" + "".join(f"{arm:>14}" for arm in arms)
          + "   (smoothed; unsmoothed in the CSV)", flush=True)
    for category in args.categories:
        model = Segmenter.pretrained(f"psb/{category}")
        for item in datasets.load("psb", category=category, split="test", split_index=0, progress=False):
            mesh, labels, times = subdivided(item, args.faces)
            given = segment(item.mesh, model)
            row = {"category": category, "mesh": item.name, "subdivided": times, "faces": mesh.n_faces,
                   "as_given": accuracy(given.labels, item.labels, item.mesh.face_areas)}
            for arm in arms:
                started = time.perf_counter()
                result = segment(mesh, model, network_faces=network_faces[arm])
                row[f"{arm} seconds"] = time.perf_counter() - started
                row[arm] = accuracy(result.labels, labels, mesh.face_areas)
                row[f"{arm} unsmoothed"] = accuracy(result.unsmoothed_labels, labels, mesh.face_areas)
            rows.append(row)
            print(f"{item.name:<14}{mesh.n_faces:>9,}  {100 * row['as_given']:>9.2f}"
                  + "".join(f"{100 * row[arm]:>14.2f}" for arm in arms), flush=True)
    print("\nunit-area accuracy, % (mean over meshes): smoothed / unsmoothed")
    for category in [*args.categories, "all"]:
        chosen = [r for r in rows if category in ("all", r["category"])]
        cells = "".join(f"{arm}: {100 * np.mean([r[arm] for r in chosen]):.2f} / "
                        f"{100 * np.mean([r[f'{arm} unsmoothed'] for r in chosen]):.2f}   " for arm in arms)
        print(f"  {category:<9} ({len(chosen)} meshes)  as given: {100 * np.mean([r['as_given'] for r in chosen]):.2f}   "
              + cells)
    print("\neach budget minus the full network, points (95 % paired bootstrap interval over the meshes)")
    for arm in arms[1:]:
        for kind in ("", " unsmoothed"):
            differences = 100 * np.array([r[arm + kind] - r["full" + kind] for r in rows])
            low, high = interval(differences)
            print(f"  {arm}{kind or ' smoothed'}: {differences.mean():+.2f} [{low:+.2f}, {high:+.2f}]")
    print("\nseconds per mesh (median): " + ", ".join(f"{arm} {np.median([r[f'{arm} seconds'] for r in rows]):.1f}"
                                                   for arm in arms))
    if args.csv:
        import pandas as pd

        pd.DataFrame(rows).to_csv(args.csv, index=False)


if __name__ == "__main__":
    main()
