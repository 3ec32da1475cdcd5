"""The ``anseg`` command: train, segment, evaluate, features, models.

Examples::

    anseg train --dataset psb --category Human --split 0 -o human.pt
    anseg train --category Human --config paper --set train.width=128 -o human_paper.pt
    anseg segment human.pt mesh.off -o mesh_labels.ply
    anseg evaluate human.pt --dataset psb --category Human --split 0
    anseg features mesh.off -o mesh_features.npy

Data sets are read from ``--data`` or ``$ANSEG_DATA``. Bad input ends with a
one-line message and a non-zero exit status, never a traceback, and at once:
the outputs' folders are checked and the input read before torch is imported
or anything computed. A command's outputs are written as one: all of them, or
none (every existing file left as it was). Validation
studies, which compare settings on training meshes, belong to the study
(``python -m anseg.study.validate``), not to the library.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import warnings
from pathlib import Path

import numpy as np

EXIT_BAD_INPUT = 2
SEGMENT_DESCRIPTION = (
    "Write a face-coloured PLY (triangles) and a label file: one 0-based label per line, line k for the mesh file's "
    "face k, in the file's order whatever it groups faces by (OBJ materials, objects, groups). A polygon of k sides is "
    "one line: it is segmented as k - 2 triangles, a fan from its first corner, and takes the label that covers most "
    "of its area. A glTF/GLB scene is one shape, its meshes in the scene's node order; in a scene that places one mesh "
    "more than once each placement is segmented on its own, and their lines follow one another in node order.")


def _non_negative(text: str) -> float:
    value = float(text)
    if not value >= 0:
        raise argparse.ArgumentTypeError(f"must be a number >= 0, got {text}")
    return value


class _Deferred:
    """Choices or a default that argparse reads only to check a given value or to print help.

    The modules that define them import torch, which takes seconds; a
    command that fails on its input should not wait for it.
    """

    def __init__(self, load):
        self._load = load

    def __contains__(self, value) -> bool:
        return value in self._load()

    def __iter__(self):
        return iter(self._load())

    def __str__(self) -> str:
        return ",".join(self._load())


def _config_names():
    from anseg.configs import NAMED

    return list(NAMED)


def _downsampling_modes():
    from anseg.pipeline import DOWNSAMPLING_MODES

    return DOWNSAMPLING_MODES


def _default_groups():
    from anseg.pipeline import SegmentConfig

    return SegmentConfig().groups


def _add_data_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--dataset", default="psb", help="data set name (default: psb; see anseg.datasets.DATASETS)")
    parser.add_argument("--category", default=None, help="category, e.g. Human for psb, figure for synthetic")
    parser.add_argument("--split", type=int, default=0, help="split index (default: 0)")
    parser.add_argument("--data", default=None, help="folder holding the data sets (default: $ANSEG_DATA)")


def _parser() -> argparse.ArgumentParser:
    from anseg import __version__
    from anseg.mesh_files import SUPPORTED_SUFFIXES

    mesh_help = f"mesh file ({', '.join(SUPPORTED_SUFFIXES)})"
    parser = argparse.ArgumentParser(prog="anseg", description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__.split("\n\n", 1)[1])
    parser.add_argument("--version", action="version", version=f"anseg {__version__}")
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    train = commands.add_parser("train", help="train a model on one category",
                                description="Train on a split's training meshes and save the model.")
    _add_data_options(train)
    train.add_argument("-o", "--output", required=True, type=Path, help="model file to write (.pt)")
    train.add_argument("--config", choices=_Deferred(_config_names), default="default", metavar="NAME",
                       help="named configuration (anseg.configs): %(choices)s (default: %(default)s)")
    train.add_argument("--set", dest="overrides", default="", metavar="FIELD=VALUE[,...]",
                       help="settings on top of the configuration: SegmentConfig fields, TrainConfig ones as train.FIELD")
    train.add_argument("--mode", choices=_Deferred(_downsampling_modes), metavar="MODE",
                       help="downsampling mode: %(choices)s (default: the configuration's)")
    train.add_argument("--cycles", type=int, help="downsampling cycles N (default: the configuration's)")
    train.add_argument("--ratio", type=float, help="faces kept per cycle (default: the configuration's)")
    train.add_argument("--epochs", type=int, help="epochs (default: the configuration's)")
    train.add_argument("--seed", type=int, help="random seed (default: the configuration's)")
    train.add_argument("--device", help="cpu, cuda or auto (default: the configuration's)")
    train.add_argument("--evaluate", action="store_true", help="also evaluate on the split's test meshes")

    segment = commands.add_parser("segment", help="segment a mesh file with a trained model", description=SEGMENT_DESCRIPTION)
    segment.add_argument("paths", nargs="+", type=Path, metavar="[MODEL] MESH",
                         help=f"a model file written by `anseg train` (or --model), then the {mesh_help}")
    segment.add_argument("-m", "--model", dest="model_name", metavar="NAME_OR_FILE",
                         help="a pretrained model listed by `anseg models` (e.g. psb/Human), or a model file")
    segment.add_argument("-o", "--output", type=Path, help="coloured PLY to write (default: <mesh>_labels.ply)")
    segment.add_argument("--labels", type=Path,
                         help="label file to write, one line per face of the mesh file (default: <output>.txt)")
    segment.add_argument("--html", type=Path, metavar="FILE",
                         help="also write a standalone HTML view (opens in any browser, no server): the labels, "
                              "every level with its attention, the confidence and a legend")
    shown = segment.add_mutually_exclusive_group()
    shown.add_argument("--progress", dest="progress", action="store_const", const=True, default=None,
                       help="show the progress of a large mesh on stderr even where it is not a terminal "
                            "(default: where it is one)")
    shown.add_argument("-q", "--quiet", dest="progress", action="store_const", const=False, help="show no progress")
    segment.add_argument("--smooth-weight", type=_non_negative, default=None,
                         help="graph-cut weight (default: the model's; 0 turns smoothing off)")
    segment.add_argument("--repair", action="store_true",
                         help="merge duplicate vertices, drop degenerate and repeated faces and cut non-manifold edges and "
                              "vertices apart first; labels are written per input face")

    evaluate = commands.add_parser("evaluate", help="score a trained model on a split's test meshes",
                                   description="Eq. 5 on the test meshes: unit-area (primary), raw-area and face readings.")
    evaluate.add_argument("model", type=Path, metavar="MODEL",
                          help="a model file written by `anseg train`, or a pretrained model listed by `anseg models`")
    _add_data_options(evaluate)
    evaluate.add_argument("--json", type=Path, help="also write the scores to this JSON file")

    feats = commands.add_parser("features", help="compute per-face features of a mesh",
                                description="Write the (F, D) per-face feature matrix as .npy.")
    feats.add_argument("mesh", type=Path, help=mesh_help)
    feats.add_argument("-o", "--output", required=True, type=Path, help=".npy file to write")
    feats.add_argument("--groups", default=_Deferred(_default_groups),
                       help="comma-separated feature groups (default: %(default)s)")
    feats.add_argument("-q", "--quiet", action="store_true", help="no progress bar (shown on large meshes at a terminal)")
    feats.add_argument("--repair", action="store_true",
                       help="repair the mesh first, as `segment --repair` does; rows follow the repaired faces")

    models = commands.add_parser("models", help="list the pretrained models shipped with anseg",
                                 description="The pretrained models `anseg segment --model NAME` and `anseg evaluate NAME` "
                                             "take, with their model cards' summary, code revision and date.")
    models.add_argument("-v", "--verbose", action="store_true",
                        help="also each model's label names (read from the model files: slower) and the rest of its card")
    return parser


def _model_file(name_or_path) -> Path:
    """The model file the user names: a file, or a pretrained model's name (`anseg models`); checked without torch."""
    from anseg import pretrained

    path = Path(name_or_path)
    if path.is_dir():
        raise ValueError(f"{path}: is a directory, not a model file")
    if path.is_file():
        return path
    if str(name_or_path) in pretrained.cards():
        return pretrained.path(str(name_or_path))
    raise ValueError(f"{path}: no such model file, nor a pretrained model (`anseg models` lists them: "
                     f"{', '.join(pretrained.names()) or 'none are shipped with this installation'})")


def _load_model(path: Path):
    from anseg.pipeline import Segmenter
    from anseg.train import resolve_device

    return Segmenter.load(path, device=resolve_device("auto"))


def _check_outputs(*paths: Path | None) -> None:
    """Fail now, before any work, where an output cannot be written: a folder in its place, a file where its folder
    should be, a folder this process may not write to, or two outputs on one path. Folders that do not exist yet are
    made when writing."""
    seen = set()
    for path in filter(None, paths):
        if path.resolve() in seen:
            raise ValueError(f"{path}: given for two outputs")
        seen.add(path.resolve())
        if path.is_dir():
            raise ValueError(f"{path}: is a directory; give a file name")
        folder = path.absolute().parent
        while not folder.exists() and folder != folder.parent:
            folder = folder.parent
        if not folder.is_dir():
            raise ValueError(f"{path}: cannot be written: {folder} is a file, not a folder")
        if not os.access(folder, os.W_OK | os.X_OK):
            raise ValueError(f"{path}: cannot be written: no permission to write in {folder}")


def _train(args) -> None:
    _check_outputs(args.output)
    from anseg import datasets
    from anseg.configs import overrides
    from anseg.pipeline import SegmentConfig
    from anseg.train import TrainConfig, evaluate, fit

    segment, train = overrides(args.config, args.overrides)
    flags = {"mode": args.mode, "cycles": args.cycles, "ratio": args.ratio, "seed": args.seed}
    segment.update({k: v for k, v in flags.items() if v is not None})
    flags = {"epochs": args.epochs, "seed": args.seed, "device": args.device}
    train.update({k: v for k, v in flags.items() if v is not None})
    config, settings = SegmentConfig(**segment), TrainConfig(**train)  # a bad value fails before the data is read
    train_set = datasets.load(args.dataset, category=args.category, split="train", split_index=args.split, root=args.data)
    model = fit(train_set, train_set[0].label_names, config, settings, checkpoint=args.output.with_suffix(".ckpt"))
    model.save(args.output)
    args.output.with_suffix(".ckpt").unlink(missing_ok=True)
    print(f"model written to {args.output}")
    if args.evaluate:
        test_set = datasets.load(args.dataset, category=args.category, split="test", split_index=args.split, root=args.data)
        _print_scores(evaluate(model, test_set))


def _print_scores(scores: dict) -> None:
    for name in ("smoothed", "unsmoothed"):
        readings = ", ".join(f"{k} {100 * v:.2f} %" for k, v in scores[name].items())
        print(f"{name:>10}: {readings}")


def _segment(args) -> None:
    from anseg.mesh_files import WRITABLE_SUFFIXES, load_shapes

    if args.model_name is not None:
        if len(args.paths) != 1:
            raise ValueError("with --model, give only the mesh file")
        model_file, args.mesh = _model_file(args.model_name), args.paths[0]
    else:
        if len(args.paths) != 2:
            raise ValueError("give a model file and a mesh file, or --model NAME and a mesh file "
                             "(`anseg models` lists the names)")
        model_file, args.mesh = _model_file(args.paths[0]), args.paths[1]
    output = args.output or args.mesh.with_name(f"{args.mesh.stem}_labels.ply")
    label_path = args.labels or output.with_suffix(".txt")
    if output.suffix.lower() not in WRITABLE_SUFFIXES:
        raise ValueError(f"{output}: cannot write {output.suffix!r} (the coloured mesh is one of {', '.join(WRITABLE_SUFFIXES)})")
    _check_outputs(output, label_path, args.html)
    shapes = _repaired(args.mesh, load_shapes(args.mesh, validate=not args.repair), args.repair)
    if args.html and len(shapes) > 1:
        raise ValueError(f"{args.mesh}: --html draws one object, and this scene holds {len(shapes)} (one mesh placed "
                         "more than once); leave out --html, or export one placement")
    model = _load_model(model_file)

    from anseg.cache import atomic_write_all
    from anseg.mesh import Mesh, labels_for_input_faces
    from anseg.mesh_files import labels_for_file_faces, save_mesh
    from anseg.pipeline import segment
    from anseg.viz import label_colors

    config = model.config
    if args.smooth_weight is not None:
        from dataclasses import replace

        config = replace(config, smooth_weight=args.smooth_weight)
    results, per_file_face = [], []
    for input_mesh, file_face, mesh, face_map in shapes:  # each object on its own, in the file's order
        result = segment(mesh, model, config, device=next(model.network.parameters()).device, progress=args.progress)
        labels = result.labels
        if face_map is not None:  # back to the input faces, dropped ones included
            labels = labels_for_input_faces(result.labels, face_map, input_mesh)
        results.append(result)
        per_file_face.append(labels_for_file_faces(labels, file_face, input_mesh))  # one line per face, polygons whole
    labels, segmented = np.concatenate(per_file_face), np.concatenate([r.labels for r in results])
    meshes = [mesh for *_, mesh, _ in shapes]
    offsets = np.cumsum([0, *(m.n_vertices for m in meshes[:-1])])
    joined = Mesh(np.concatenate([m.vertices for m in meshes]), np.concatenate([m.faces + o for m, o in zip(meshes, offsets)]))
    writes = {output: lambda tmp: save_mesh(tmp, joined, face_colors=label_colors(segmented, model.n_classes)),
              label_path: lambda tmp: np.savetxt(tmp, labels, fmt="%d")}
    if args.html:
        from anseg.pipeline import fill_attention
        from anseg.viewer import write_html

        fill_attention(model, results[0].levels)  # every level's attention panel, not only those that drove a collapse
        writes[args.html] = lambda tmp: write_html(results[0], model.label_names, tmp, title=args.mesh.name)
    atomic_write_all(writes)  # all the outputs or none, each complete, even when interrupted
    counts = np.bincount(segmented, minlength=model.n_classes)
    triangles = f" ({joined.n_faces} triangles)" if joined.n_faces != len(labels) else ""
    objects = f" in {len(shapes)} objects" if len(shapes) > 1 else ""
    print(f"{len(labels)} faces{triangles}{objects} -> {output} and {label_path}"
          + (f" (view: {args.html})" if args.html else ""))
    for name, count in zip(model.label_names, counts):
        print(f"  {name}: {count} faces")


def _evaluate(args) -> None:
    model_file = _model_file(args.model)
    _check_outputs(args.json)
    from anseg import datasets
    from anseg.cache import atomic_write
    from anseg.train import evaluate

    model = _load_model(model_file)
    test_set = datasets.load(args.dataset, category=args.category, split="test", split_index=args.split, root=args.data)
    scores = evaluate(model, test_set)
    _print_scores(scores)
    if args.json:
        scores.pop("predictions")
        atomic_write(args.json, lambda tmp: tmp.write_text(json.dumps(scores, indent=1)))


def _repaired(path: Path, shapes, repair: bool) -> list[tuple]:
    """(input mesh, file_face, mesh to segment, face_map or None) of each object, repaired with ``--repair``; a mesh
    that cannot be repaired is a MeshError that names the file."""
    from anseg import MeshError
    from anseg import repair as repaired

    try:
        return [(mesh, file_face, *(repaired(mesh) if repair else (mesh, None))) for mesh, file_face in shapes]
    except MeshError as exc:
        raise MeshError(f"{path}: {exc}") from None


def _features(args) -> None:
    from anseg.mesh_files import load_shapes

    _check_outputs(args.output)
    shapes = _repaired(args.mesh, load_shapes(args.mesh, validate=not args.repair), args.repair)
    from anseg import features
    from anseg.cache import atomic_write

    groups = [g.strip() for g in str(args.groups).split(",") if g.strip()]
    x = np.concatenate([features.compute(mesh, groups=groups, progress=not args.quiet) for _, _, mesh, _ in shapes])

    def write(tmp: Path) -> None:
        with open(tmp, "wb") as handle:  # np.save(path) would append ".npy" to a name without it
            np.save(handle, x)

    atomic_write(args.output, write)
    print(f"{x.shape[0]} faces x {x.shape[1]} features -> {args.output}")


def _models(args) -> None:
    from anseg import pretrained

    if not pretrained.names():
        print("no pretrained models are shipped with this installation; `anseg train` makes one")
    for name in pretrained.names():
        card = pretrained.card(name)
        print(f"{pretrained.describe(name)}; revision {str(card.get('code_revision', '?'))[:8]}, "
              f"{str(card.get('date', '?'))[:10]}")
        if args.verbose:
            try:
                labels = ", ".join(_load_model(pretrained.path(name)).label_names)
            except ValueError as exc:  # a damaged file, or one for other features: say so, and list the others
                labels = f"unreadable ({exc})"
            print(f"    labels: {labels}")
            print(f"    {card.get('test_meshes', '?')} test meshes; trained on {card.get('trained_on', '?')} "
                  f"at {card.get('date', '?')}, code revision {card.get('code_revision', '?')}, stored run "
                  f"{card.get('run', '?')}")


def main(argv: list[str] | None = None) -> int:
    from anseg.datasets import DatasetError
    from anseg.mesh import REPAIR_HINT, MeshError

    argv = sys.argv[1:] if argv is None else list(argv)
    args = _parser().parse_args(argv)
    handlers = {"train": _train, "segment": _segment, "evaluate": _evaluate, "features": _features, "models": _models}
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", UserWarning)
            handlers[args.command](args)
        for warning in caught:  # ours, one line each, not in Python's file:line form
            if warning.category.__module__.startswith("anseg"):
                print(f"anseg {args.command}: warning: {warning.message}", file=sys.stderr)
    except BrokenPipeError:  # the reader left (`anseg models | head`): stop quietly, as Unix tools do
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # so the exit's flush cannot fail again
        return 141
    except (MeshError, DatasetError, ValueError, OSError) as exc:
        if isinstance(exc, OSError) and exc.filename is not None:  # "PATH: reason", not Python's "[Errno N] reason: 'PATH'"
            message = f"{exc.filename}: {exc.strerror or exc}"
        else:  # the library names its repair anseg.repair(mesh); here it is a flag
            message = str(exc).replace(REPAIR_HINT, "--repair")
        print(f"anseg {args.command}: error: {message}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        print("anseg: interrupted", file=sys.stderr)
        return 130
    return 0


if __name__ == "__main__":
    sys.exit(main())
