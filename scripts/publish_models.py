"""Ship the pretrained models (Table I's split-0 runs, the human set, the COSEG sets) and the figures' models.

    python scripts/publish_models.py --config default [--data DIR]

Takes, for every run of those notebooks' real plan under ``--config``, the
stored result (``results/runs/<key>.json``) and its model
(``models/<key>.pt``), and writes it with its model card into
``anseg/pretrained/`` (:func:`publish`: float16 where that changes no test
label). The models whose output Figs. 4-8, 10 and 12 render and that are
not shipped already are copied as they are into ``results/models/``, so that
the notebooks regenerate from a clone without training. A run whose model
is shipped already (a card names the run) is left as it is, so the script
can be rerun as runs land. Trains nothing: a
run whose result or model is not here is listed and left out. The test
meshes are read only to check the float16 copy against the trained model,
after the run's one reading of them, and to measure the card's pose
agreement: per transform of ``benchmarks/metamorphic.py`` (a rotation,
a scale and shift, new face and vertex orders, flipped faces, a mirror), the
least share of a test mesh's area whose label the shipped model keeps.
"""

from __future__ import annotations

import anseg  # noqa: F401  first: importing anseg pins the float kernels before NumPy and torch load

# isort: split
import argparse
import io
import json
import shutil
import sys
from pathlib import Path

import numpy as np

from anseg import datasets, pretrained
from anseg.pipeline import Segmenter, feature_code, segment
from anseg.study.plan import notebook_parameters, notebook_runs, planned_experiment
from anseg.study.store import REPO, ResultStore, trained_on

# which notebook runs become which shipped names
# (Table I's split 0 also holds the plain reading's runs: those are not the configuration shipped)
SOURCES = {"table1_psb.ipynb": lambda run: f"psb/{run.category}" if run.split == 0 and "configuration" not in run.row
           else None,
           "table3_human.ipynb": lambda run: "human_seg",
           "table2_coseg.ipynb": lambda run: run.dataset if run.category is None else None}
# the runs whose models the figure notebooks load (fig4: every run, its claims read each split's; fig12: the first category,
# split 0, rendered)
RENDERED = {"fig4_attention.ipynb": lambda run, p: True,
            "fig12_features.ipynb": lambda run, p: run.split == 0 and run.category == p["categories"][0]}
FIGURE_MODELS = REPO / "results" / "models"
sys.path.insert(0, str(REPO / "benchmarks"))  # the metamorphic benchmark's transforms, for the pose agreement
from metamorphic import TRANSFORMS, compare, label_fn  # noqa: E402


def pose_agreement(model, test_set) -> dict[str, float]:
    """Per metamorphic transform: the least share of a test mesh's area whose label ``model`` keeps under it."""
    labels = label_fn(model)
    worst = dict.fromkeys(TRANSFORMS, 1.0)
    for item in test_set:
        for name, found in compare(labels, item.mesh, None, list(TRANSFORMS)).items():
            worst[name] = min(worst[name], found["agreement"])
    return worst


def publish(model, name: str, result: dict, test_set, configuration: str, out: Path = pretrained.MODELS) -> dict:
    """Write ``model`` as the shipped model ``name`` with its card, from the stored ``result`` it was trained in.

    Stores float16 weights when segmenting ``test_set`` with them gives the
    same labels as float32 on every face, float32 otherwise; the card records
    which, and the accuracy from ``result`` (the run's one reading of its
    test split).
    """
    if not name.replace("/", "").replace("_", "").isalnum() or name.count("/") > 1:
        raise ValueError(f"model names are letters, digits, '_' and one '/', got {name!r}")
    half = Segmenter.load(io.BytesIO(model.to_bytes(half=True)))
    same = all(np.array_equal(segment(m.mesh, model).labels, segment(m.mesh, half).labels) for m in test_set)
    file = f"{name.replace('/', '_')}.pt"
    out.mkdir(parents=True, exist_ok=True)
    (out / file).write_bytes(model.to_bytes(half=same))
    pose = pose_agreement(half if same else model, test_set)
    env = result["environment"]
    entry = {
        "file": file,
        "run": result["key"],
        "data": f"{result['dataset']}" + (f" {result['category']}" if result.get("category") else ""),
        "split": f"split {result.get('split_index', 0)}: {result.get('n_train', '?')} training meshes",
        "configuration": {"name": configuration, "segment": result["segment"],
                          "train": result["train"]},
        "test_accuracy": result["accuracy"],
        "test_meshes": len(test_set),
        # Eq. 5 on its own training meshes (how well it fits them; None for a run from before it was recorded)
        "training_accuracy": result.get("train_accuracy"),
        "pose_agreement": {"worst over the test meshes, per transform": pose, "least": min(pose.values())},
        "precision": "float16 (no test label changes)" if same else "float32 (float16 changed test labels)",
        "code_revision": env.get("code_revision"),
        "trained_on": trained_on(result),
        "kernels": env.get("kernels") or "each library's own (trained before the kernel pin)",
        "date": env.get("date"),
        "feature_code": feature_code(),
    }
    index = json.loads((out / "index.json").read_text()) if (out / "index.json").is_file() else {}
    index[name] = entry
    (out / "index.json").write_text(json.dumps(dict(sorted(index.items())), indent=1) + "\n")
    return entry


def _runs(notebook: str, config: str):
    """Every run of a notebook's real plan under ``config``: (run, the notebook's parameters, experiment, stored key)."""
    p = {**notebook_parameters(notebook, "real"), "config": config}
    for run in notebook_runs(notebook, p):
        experiment, options = planned_experiment(run, p)
        yield run, p, experiment, experiment.key(options)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--config", default="default", help="the named configuration the runs were trained with")
    parser.add_argument("--data", default=None, help="folder holding the data sets (default: $ANSEG_DATA)")
    args = parser.parse_args(argv)
    store, missing = ResultStore(REPO), []
    for notebook, name_of in SOURCES.items():
        for run, _, experiment, key in _runs(notebook, args.config):
            if (name := name_of(run)) is None or pretrained.of_run(key) is not None:  # not a shipped name, or shipped already
                continue
            result = store.get(key)
            if result is None or not store.model_path(key).is_file():
                missing.append(f"{name} ({key})")
                continue
            test_set = datasets.load(experiment.dataset, experiment.category, "test", experiment.split_index,
                                     root=args.data, progress=False)
            entry = publish(Segmenter.load(store.model_path(key)), name, result, test_set, args.config)
            print(f"{name}: {entry['precision']}, test accuracy {100 * entry['test_accuracy']['unit_area']:.2f} %")
    for notebook, rendered in RENDERED.items():
        for run, p, _, key in _runs(notebook, args.config):
            if not rendered(run, p) or pretrained.of_run(key) is not None or (FIGURE_MODELS / f"{key}.pt").is_file():
                continue  # not rendered, or here already
            if store.get(key) is None or not store.model_path(key).is_file():
                missing.append(f"{notebook} {run.row} ({key})")
                continue
            FIGURE_MODELS.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(store.model_path(key), FIGURE_MODELS / f"{key}.pt")
            print(f"{notebook} {run.row}: results/models/{key}.pt")
    if missing:
        print(f"not published (no stored result or model here): {', '.join(missing)}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
