"""Pretrained models shipped with the package, each with a model card, and the names that select them.

A user with a mesh of their own should not have to train first. The models
live in ``anseg/pretrained/`` beside ``index.json``, which maps every name
(``psb/Human``, ``human_seg``, ``coseg_aliens``, ...) to its file and its
card: the data and split it was trained on, the configuration with every
setting, its accuracy on the split's test meshes, the code revision, the
machine and the date. Weights are stored in float16 only where that
changes no label of those test meshes (the card says which).

A name is looked up in the index and nothing else: the file a name leads to
comes from the index, never from the name, so no user string reaches the
file system. :func:`resolve` takes a name or the path of a model file.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

MODELS = Path(__file__).resolve().parent / "pretrained"
INDEX = MODELS / "index.json"


def cards() -> dict[str, dict]:
    """Every shipped model's card, by name (empty when none are shipped)."""
    if not INDEX.is_file():
        return {}
    return json.loads(INDEX.read_text())


def names() -> list[str]:
    return sorted(cards())


def card(name: str) -> dict:
    """The model card of a shipped model; a name not in the index is a one-line ValueError listing the names."""
    known = cards()
    if name not in known:
        listed = ", ".join(sorted(known)) or "none are shipped with this installation"
        raise ValueError(f"no pretrained model {name!r}; `anseg models` lists them: {listed}")
    return known[name]


def load(name: str, device="cpu"):
    """The shipped model ``name`` as a :class:`~anseg.pipeline.Segmenter` (float32, in eval mode)."""
    from anseg.pipeline import Segmenter

    entry = card(name)
    return Segmenter.load(MODELS / Path(entry["file"]).name, device=device)


def resolve(name_or_path: str | os.PathLike, device="cpu"):
    """A model from a file the user names, or else from the shipped ones; a one-line ValueError when it is neither."""
    from anseg.pipeline import Segmenter

    path = Path(name_or_path)
    if path.is_file():
        return Segmenter.load(path, device=device)
    if str(name_or_path) in cards():
        return load(str(name_or_path), device)
    raise ValueError(f"{name_or_path}: neither a model file nor a pretrained model (`anseg models` lists them: "
                     f"{', '.join(names()) or 'none are shipped with this installation'})")


def describe(name: str) -> str:
    """One line per model for ``anseg models``: the name, what it was trained on and its test accuracy."""
    c = card(name)
    accuracy = c["test_accuracy"]["unit_area"]
    return (f"{name:<20} {c['data']}, {c['split']}; test accuracy {100 * accuracy:.2f} % (Eq. 5, unit area); "
            f"{c['configuration']['name']}, {c['precision']}")


def publish(model, name: str, result: dict, test_set, configuration: str, out: Path = MODELS) -> dict:
    """Write ``model`` as the shipped model ``name`` with its card, from the stored ``result`` it was trained in.

    Stores float16 weights when segmenting ``test_set`` with them gives the
    same labels as float32 on every face, float32 otherwise; the card records
    which, and the accuracy from ``result`` (the run's one reading of its
    test split).
    """
    import io

    import numpy as np

    from anseg.pipeline import Segmenter, feature_code, segment

    if not name.replace("/", "").replace("_", "").isalnum() or name.count("/") > 1:
        raise ValueError(f"model names are letters, digits, '_' and one '/', got {name!r}")
    half = Segmenter.load(io.BytesIO(model.to_bytes(half=True)))
    same = all(np.array_equal(segment(m.mesh, model).labels, segment(m.mesh, half).labels) for m in test_set)
    file = f"{name.replace('/', '_')}.pt"
    out.mkdir(parents=True, exist_ok=True)
    (out / file).write_bytes(model.to_bytes(half=same))
    env = result["environment"]
    entry = {
        "file": file,
        "data": f"{result['dataset']}" + (f" {result['category']}" if result.get("category") else ""),
        "split": f"split {result.get('split_index', 0)}: {result.get('n_train', '?')} training meshes",
        "configuration": {"name": configuration, "segment": result["segment"],
                          "train": result["train"]},
        "test_accuracy": result["accuracy"],
        "test_meshes": len(test_set),
        "precision": "float16 (no test label changes)" if same else "float32 (float16 changed test labels)",
        "code_revision": env.get("code_revision"),
        "trained_on": env.get("cuda") or f"CPU, {env.get('cpus')} cores",
        "date": env.get("date"),
        "feature_code": feature_code(),
    }
    index = json.loads((out / "index.json").read_text()) if (out / "index.json").is_file() else {}
    index[name] = entry
    (out / "index.json").write_text(json.dumps(dict(sorted(index.items())), indent=1) + "\n")
    return entry
