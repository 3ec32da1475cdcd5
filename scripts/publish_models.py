"""Ship the pretrained models: Table I's split-0 runs, the human set and the COSEG sets, from the result store.

    python scripts/publish_models.py --config default [--data DIR]

Takes, for every run of those notebooks' real plan under ``--config``, the
stored result (``results/runs/<key>.json``) and its model
(``results/models/<key>.pt``), and writes it with its model card into
``anseg/pretrained/`` (:func:`anseg.pretrained.publish`: float16 where that
changes no test label). Trains nothing: a run whose result or model is not
here is listed and left out. The test meshes are read only to check the
float16 copy against the trained model, after the run's one reading of them.
"""

from __future__ import annotations

import argparse
import sys

from anseg import datasets, pretrained
from anseg.experiments import REPO, ResultStore, notebook_parameters, notebook_runs, planned_experiment
from anseg.pipeline import Segmenter

# which notebook runs become which shipped names
SOURCES = {"table1_psb.ipynb": lambda run: f"psb/{run.category}" if run.split == 0 else None,
           "table3_human.ipynb": lambda run: "human_seg",
           "table2_coseg.ipynb": lambda run: run.dataset if run.category is None else None}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--config", default="default", help="the named configuration the runs were trained with")
    parser.add_argument("--data", default=None, help="folder holding the data sets (default: $ANSEG_DATA)")
    args = parser.parse_args(argv)
    store, missing = ResultStore(REPO), []
    for notebook, name_of in SOURCES.items():
        p = {**notebook_parameters(notebook, "real"), "config": args.config}
        for run in notebook_runs(notebook, p):
            if (name := name_of(run)) is None:
                continue
            experiment, options = planned_experiment(run, p)
            key = experiment.key(options)
            result = store.get(key)
            if result is None or not store.model_path(key).is_file():
                missing.append(f"{name} ({key})")
                continue
            test_set = datasets.load(experiment.dataset, experiment.category, "test", experiment.split_index,
                                     root=args.data, progress=False)
            entry = pretrained.publish(Segmenter.load(store.model_path(key)), name, result, test_set, args.config)
            print(f"{name}: {entry['precision']}, test accuracy {100 * entry['test_accuracy']['unit_area']:.2f} %")
    if missing:
        print(f"not published (no stored result or model here): {', '.join(missing)}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
