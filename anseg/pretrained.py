"""Pretrained models shipped with the package, each with a model card, and the names that select them.

A user with a mesh of their own should not have to train first. The models
live in ``anseg/pretrained/`` beside ``index.json``, which maps every name
(``psb/Human``, ``human_seg``, ``coseg_aliens``, ...) to its file and its
card: the data and split it was trained on, the configuration with every
setting, its accuracy on the split's test meshes, the code revision, the
machine, the date and the stored run it comes from (so the notebooks that
render a run's output use it where the run's own model file is absent).
Weights are stored in float16 only where that changes no label of those
test meshes (the card says which).

A name is looked up in the index and nothing else: the file a name leads to
comes from the index, never from the name, so no user string reaches the
file system. :func:`resolve` takes a name or the path of a model file;
``Segmenter.pretrained(name)`` loads one. ``scripts/publish_models.py``
writes them from the result store.
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


def _file(entry: dict) -> Path:
    """The model file a card names, inside the models' folder whatever the index says."""
    return MODELS / Path(entry["file"]).name


def path(name: str) -> Path:
    """The file of the shipped model ``name``: taken from the index, never built from the name."""
    return _file(card(name))


def of_run(key: str) -> Path | None:
    """The file of the shipped model trained in the stored run ``key`` (its card's ``run``), or None."""
    return next((_file(entry) for entry in cards().values() if entry.get("run") == key), None)


def resolve(name_or_path: str | os.PathLike) -> Path:
    """A model file the user names, or else the file of a shipped model; a one-line ValueError when it is neither."""
    given = Path(name_or_path)
    if given.is_file():
        return given
    if str(name_or_path) in cards():
        return path(str(name_or_path))
    raise ValueError(f"{name_or_path}: neither a model file nor a pretrained model (`anseg models` lists them: "
                     f"{', '.join(names()) or 'none are shipped with this installation'})")


def describe(name: str) -> str:
    """One line per model for ``anseg models``: the name, what it was trained on and its test accuracy."""
    c = card(name)
    accuracy = c["test_accuracy"]["unit_area"]
    return (f"{name:<20} {c['data']}, {c['split']}; test accuracy {100 * accuracy:.2f} % (Eq. 5, unit area); "
            f"{c['configuration']['name']}, {c['precision']}")
