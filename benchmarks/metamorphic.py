"""Metamorphic benchmark: does a segmentation survive a change of pose, scale or file layout?

    ANSEG_DATA=/work/shared/datasets python benchmarks/metamorphic.py [MODEL ...] [--data psb/Hand | human_seg]
                                     [--meshes N] [--transforms rotation mirror ...] [--seed 0] [--csv PATH]
                                     [--set canonical=true,...]

MODEL is a shipped name (``anseg models`` lists them; default: ``psb/Hand``)
or a model file. Each test mesh is segmented as it is and after each
transform below; the transformed mesh's labels are carried back to the
original faces, and the script prints, per mesh and transform:

* agreement: the share of the surface area (the original mesh's face areas)
  whose label is the same as on the untransformed mesh, in %;
* the accuracy change against the ground truth, in points of Eq. 5
  (area-weighted, ``anseg.metrics.accuracy``), transformed minus original;

then per transform the mean and worst agreement and the mean accuracy change.
``--set`` segments with other settings than the model's own (SegmentConfig
fields in the field=value syntax of ``anseg.configs``; ``canonical=true``
puts every mesh in its canonical pose and order first).

The rule: a segmentation is a function of the surface, so none of these
transforms should change a label. Each one is a change that leaves the
surface (and its outward side) as it is:

* ``rotation``: a fixed random rotation (uniform on SO(3), from ``--seed``);
* ``scale_shift``: coordinates x1000, then shifted by 10 bounding-box
  diagonals (of the scaled mesh) along (1, -2, 3) / |(1, -2, 3)|;
* ``face_order``: the faces in a random order (from ``--seed``);
* ``vertex_order``: the vertices in a random order, the faces re-indexed;
* ``flip``: every face's vertex order reversed (the normals point inward);
* ``mirror``: x -> -x, with every face reversed so that it still faces outward.

Strictly a mirror changes the shape (left and right swap), and a flip its
outward side; the labels of the benchmark's categories name no side, so the
two are read like the others. The test meshes are, by default, those the
model was tested on (its card's data: a PSB category's split-0 test meshes,
or a MeshCNN set's test meshes); a model file needs ``--data``.
"""

from __future__ import annotations

import anseg  # noqa: F401  first: importing anseg pins the float kernels before NumPy and torch load

# isort: split
import argparse
import csv
import dataclasses
import sys
import time
import warnings

import numpy as np

from anseg import datasets, pretrained
from anseg.configs import parse_overrides
from anseg.mesh import Mesh
from anseg.metrics import accuracy
from anseg.pipeline import Segmenter, segment


def _random_rotation(rng) -> np.ndarray:
    """A rotation uniform on SO(3): QR of a Gaussian matrix, signs fixed so that R is unique and det R = +1."""
    q, r = np.linalg.qr(rng.standard_normal((3, 3)))
    q = q * np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q


def rotation(mesh: Mesh, rng):
    return Mesh(mesh.vertices @ _random_rotation(rng).T, mesh.faces), None


def _shifted(vertices: np.ndarray) -> np.ndarray:
    """``vertices`` moved by 10 bounding-box diagonals along (1, -2, 3): far from the origin, as a scan may be."""
    diagonal = np.linalg.norm(vertices.max(axis=0) - vertices.min(axis=0))
    return vertices + 10.0 * diagonal * np.array([1.0, -2.0, 3.0]) / np.sqrt(14.0)


def scale_shift(mesh: Mesh, rng):
    return Mesh(_shifted(mesh.vertices * 1000.0), mesh.faces), None


def rigid_motion(mesh: Mesh, seed: int = 0) -> Mesh:
    """``rotation`` then the shift of ``scale_shift`` without its scaling: a rigid motion (what tests/ guard)."""
    rotated, _ = rotation(mesh, np.random.default_rng(seed))
    return Mesh(_shifted(rotated.vertices), mesh.faces)


def face_order(mesh: Mesh, rng):
    order = rng.permutation(mesh.n_faces)
    return Mesh(mesh.vertices, mesh.faces[order]), order


def vertex_order(mesh: Mesh, rng):
    order = rng.permutation(mesh.n_vertices)  # new vertex i is old vertex order[i]
    new_index = np.empty_like(order)
    new_index[order] = np.arange(len(order))
    return Mesh(mesh.vertices[order], new_index[mesh.faces]), None


def flip(mesh: Mesh, rng):
    return Mesh(mesh.vertices, mesh.faces[:, ::-1]), None


def mirror(mesh: Mesh, rng):
    return Mesh(mesh.vertices * np.array([-1.0, 1.0, 1.0]), mesh.faces[:, ::-1]), None


# name: f(mesh, rng) -> (transformed mesh, the original face of each new face, or None when faces keep their order)
TRANSFORMS = {f.__name__: f for f in (rotation, scale_shift, face_order, vertex_order, flip, mirror)}
RIGID = ("rotation", "scale_shift")


def transformed(mesh: Mesh, name: str, seed: int = 0):
    """``mesh`` under the transform ``name`` (its random parts drawn from ``seed``), and its faces' original indices."""
    return TRANSFORMS[name](mesh, np.random.default_rng(seed))


def to_original(labels: np.ndarray, origin: np.ndarray | None) -> np.ndarray:
    """Labels of a transformed mesh's faces, in the original face order."""
    if origin is None:
        return labels
    back = np.empty_like(labels)
    back[origin] = labels
    return back


def agreement(a: np.ndarray, b: np.ndarray, areas: np.ndarray) -> float:
    """The share of the surface area where two labellings agree."""
    return float(areas[a == b].sum() / areas.sum())


def label_fn(model: Segmenter, config=None):
    """Per-face labels of a mesh under ``model`` (with ``config``, else its own settings), its collapse warnings
    silenced (a small mesh is read the same way)."""
    def labels(mesh: Mesh) -> np.ndarray:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return segment(mesh, model, config).labels
    return labels


def compare(labels, mesh: Mesh, truth: np.ndarray | None, names, seed: int = 0) -> dict[str, dict]:
    """Per transform: agreement with the untransformed labels and the accuracy change (both fractions)."""
    base = labels(mesh)
    areas = mesh.face_areas
    base_accuracy = accuracy(base, truth, areas) if truth is not None else np.nan
    out = {}
    for name in names:
        moved, origin = transformed(mesh, name, seed)
        back = to_original(labels(moved), origin)
        change = accuracy(back, truth, areas) - base_accuracy if truth is not None else np.nan
        out[name] = {"agreement": agreement(back, base, areas), "accuracy_change": change, "accuracy": base_accuracy}
    return out


def test_meshes(model_name: str, data: str | None):
    """The test meshes of ``data`` ("psb/<Category>" or a MeshCNN set), else of the shipped model's card."""
    if data is None:
        if model_name not in pretrained.cards():
            raise ValueError(f"{model_name}: a model file names no test data; say which with --data psb/<Category> or human_seg")
        data = pretrained.card(model_name)["data"].replace(" ", "/")
    name, _, category = data.partition("/")
    if name == "psb":
        if category not in datasets.PSB_CATEGORIES:
            raise ValueError(f"{data}: not a PSB category (one of {', '.join(datasets.PSB_CATEGORIES)})")
        return data, datasets.load("psb", category, "test", 0, progress=False)
    if name in ("coseg_aliens", "coseg_chairs", "coseg_vases", "human_seg") and not category:
        return data, datasets.load(name, split="test", progress=False)
    raise ValueError(f"{data}: test data must be psb/<Category>, coseg_aliens, coseg_chairs, coseg_vases or human_seg")


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("models", nargs="*", default=["psb/Hand"], help="shipped model names or model files (default: psb/Hand)")
    parser.add_argument("--data", help="the test meshes: psb/<Category> or a MeshCNN set (default: the model card's)")
    parser.add_argument("--meshes", type=int, help="only the first N test meshes")
    parser.add_argument("--transforms", nargs="+", default=list(TRANSFORMS), choices=list(TRANSFORMS), metavar="NAME",
                        help=f"of {', '.join(TRANSFORMS)} (default: all)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the rotation and the permutations")
    parser.add_argument("--csv", help="write one row per model, mesh and transform here")
    parser.add_argument("--set", default="", metavar="OVERRIDES",
                        help="segmentation settings instead of the model's own, field=value,... (default: none)")
    args = parser.parse_args(argv)
    if args.meshes is not None and args.meshes < 1:
        parser.error("--meshes must be at least 1")
    try:
        settings, train_settings = parse_overrides(args.set)
    except ValueError as problem:
        parser.error(str(problem))
    if train_settings:
        parser.error("--set takes segmentation settings only: a model's training is done")

    rows = []
    for model_name in args.models:
        try:
            model = Segmenter.load(pretrained.resolve(model_name))
            data, items = test_meshes(model_name, args.data)
        except (ValueError, datasets.DatasetError) as problem:
            sys.exit(f"error: {problem}")
        items = items[: args.meshes]
        labels = label_fn(model, dataclasses.replace(model.config, **settings))
        print(f"{model_name} on {len(items)} {data} test meshes; transforms seeded {args.seed}"
              + (f"; settings {args.set}" if args.set else ""))
        print(f"{'mesh':<14}{'faces':>7}{'acc %':>7}" + "".join(f"{t:>14}" for t in args.transforms)
              + f"{'seconds':>9}   (agreement % / accuracy change, points)")
        for item in items:
            started = time.perf_counter()
            result = compare(labels, item.mesh, item.labels, args.transforms, args.seed)
            seconds = time.perf_counter() - started
            cells = "".join(f"{100 * r['agreement']:>7.1f}/{100 * r['accuracy_change']:>+6.1f}" for r in result.values())
            print(f"{item.name:<14}{item.mesh.n_faces:>7}{100 * result[args.transforms[0]]['accuracy']:>7.1f}{cells}"
                  f"{seconds:>9.1f}", flush=True)
            rows += [{"model": model_name, "data": data, "mesh": item.name, "faces": item.mesh.n_faces, "transform": t,
                      "seed": args.seed, "settings": args.set, "agreement": r["agreement"], "accuracy": r["accuracy"],
                      "accuracy_change": r["accuracy_change"]} for t, r in result.items()]
        print(f"summary for {model_name}:")
        print(f"  {'transform':<14}{'mean agreement %':>18}{'worst %':>9}{'mean change, points':>21}")
        for t in args.transforms:
            mine = [r for r in rows if r["model"] == model_name and r["transform"] == t]
            agree = [r["agreement"] for r in mine]
            change = np.mean([r["accuracy_change"] for r in mine])
            print(f"  {t:<14}{100 * np.mean(agree):>18.2f}{100 * min(agree):>9.2f}{100 * change:>+21.2f}")
    if args.csv and rows:
        with open(args.csv, "w", newline="") as handle:
            writer = csv.DictWriter(handle, fieldnames=list(rows[0]))
            writer.writeheader()
            writer.writerows(rows)


if __name__ == "__main__":
    main()
