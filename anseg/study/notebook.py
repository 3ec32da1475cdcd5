"""What every notebook shares, in one call: ``nb = start("table1_psb", globals())``.

A notebook's parameter cell (papermill fills it in) defines its parameters;
:func:`start` reads them from the notebook's namespace, makes the output
folders, says plainly when the data is synthetic, prints the run record and
returns a :class:`NotebookRun`. That object gives the notebook its planned
runs (the one declaration in :func:`anseg.study.plan.notebook_runs`) with
their stored or freshly trained results, their models and test meshes; its
:meth:`~NotebookRun.finish` writes the record, wall time included, beside
the notebook's results.
"""

from __future__ import annotations

import json
import os
import time
from dataclasses import asdict
from pathlib import Path

from anseg.pipeline import SegmentConfig, Segmenter
from anseg.study.plan import (
    COMMON,
    PLAIN_READING,
    PLANS,
    RECORD_CONFIGURATIONS,
    PlannedRun,
    notebook_runs,
    notebook_settings,
    papers_method_file,
    planned_experiment,
    resolve_categories,
)
from anseg.study.runner import run_experiment
from anseg.study.store import NOT_RECORDED, REPO, ResultStore, cpu_of, environment, trained_on

SYNTHETIC_NOTICE = (
    "**Synthetic data: a check that this notebook runs, not a reproduction.** {smoke}"
    "The paper has no numbers for these shapes, so none are set beside ours. "
    "`python -m anseg.study.reproduce --data real` runs the benchmark."
)


def percent(accuracy: dict) -> dict:
    """The readings of Eq. 5 in a result (unit_area, raw_area, faces), in percent."""
    return {reading: 100 * value for reading, value in accuracy.items()}


def median_mesh(per_mesh: list[dict]) -> dict:
    """The median entry of a run's per-mesh accuracies (of an even count, the lower of the middle two).

    The mesh a figure renders is picked by this rule, so that it shows a typical mesh, not the first or the best.
    """
    ranked = sorted(per_mesh, key=lambda entry: entry["accuracy"])
    return ranked[(len(ranked) - 1) // 2]


def table_row(run: PlannedRun, result: dict) -> dict:
    """One line of a notebook's runs table: the run's row, its accuracy in %, its training time, machine and key."""
    return {**run.row, **percent(result["accuracy"]), "train_seconds": round(result["train_seconds"], 1),
            "trained_on": trained_on(result), "key": result["key"]}


class NotebookRun:
    """One execution of one notebook: its parameters, settings, planned runs, outputs and record."""

    def __init__(self, name: str, parameters: dict):
        if f"{name}.ipynb" not in PLANS:
            raise ValueError(f"no notebook {name!r} in the plan; known: {', '.join(sorted(PLANS))}")
        self.name = name
        self.started = time.time()  # the wall time of the record counts from here
        self.parameters = resolve_categories(parameters)
        self.out = Path(parameters["output_dir"])
        self.store = ResultStore(self.out)
        self.results_dir, self.figures_dir = self.out / "results", self.out / "figures"
        for folder in (self.results_dir, self.figures_dir):
            folder.mkdir(parents=True, exist_ok=True)
        p = self.parameters
        self.synthetic, self.smoke = p["dataset"] == "synthetic", p["smoke"]
        self.shape_options, self.segment_options, self.train = notebook_settings(p)
        self.planned = notebook_runs(f"{name}.ipynb", p)
        self.read: dict[str, dict] = {}  # the stored results this notebook read, by key
        self.record = self._record(parameters)

    def result(self, run: PlannedRun) -> dict:
        """The stored result of a planned run, or a fresh one trained and evaluated here (and stored)."""
        experiment, options = planned_experiment(run, self.parameters)
        result = run_experiment(experiment, out_dir=self.out, progress=False, **options)
        self.read[result["key"]] = result
        return result

    def results(self) -> list[tuple[PlannedRun, dict]]:
        """Every planned run with its result, in the plan's order."""
        return [(run, self.result(run)) for run in self.planned]

    def stored_result(self, run: PlannedRun, config: str) -> dict | None:
        """The stored result of ``run`` under another named configuration, or None: read, never trained."""
        experiment, options = planned_experiment(run, {**self.parameters, "config": config})
        return self.store.get(experiment.key(options))

    def other_configuration(self, config: str, select=None) -> tuple[list[tuple[PlannedRun, dict]], int]:
        """The runs this notebook plans under another named configuration (those ``select`` keeps, where given) that
        the store holds, with their results (read, never trained), and how many it plans."""
        planned = [run for run in notebook_runs(f"{self.name}.ipynb", {**self.parameters, "config": config})
                   if select is None or select(run)]
        found = [(run, result) for run in planned if (result := self.stored_result(run, config)) is not None]
        self.read.update({result["key"]: result for _, result in found})
        return found, len(planned)

    def papers_method(self, runs_file: str, select=None):
        """This notebook's runs under the paper's configuration, as a runs table written for the claims ledger
        (:func:`~anseg.study.plan.papers_method_file` of ``runs_file``), and None; or None and what to say instead
        (Markdown) where the notebook runs that configuration itself or some of its runs are not stored yet (a
        table from an earlier run is removed then: part of the runs must not stand for all of them).

        ``select`` (a test on a :class:`PlannedRun`) keeps part of the plan, for a table of its own: only
        those runs are read and need to be stored."""
        import pandas as pd

        if self.parameters["config"] == PLAIN_READING:
            return None, ("This notebook runs the paper's method as written itself: the readings above are the ones "
                          "the ledger judges.")
        path = self.results_dir / papers_method_file(runs_file)
        found, planned = self.other_configuration(PLAIN_READING, select)
        if len(found) < planned:
            path.unlink(missing_ok=True)
            return None, (f"**The paper's method as written** (`{PLAIN_READING}` configuration): {len(found)} of its "
                          f"{planned} runs are stored. The claims ledger judges this notebook's claims on those runs "
                          f"once all are there (`python -m anseg.study.reproduce --config {PLAIN_READING} --only "
                          f"{self.name} --train-only`, with `--data real` for the benchmark); until then it judges "
                          "none of them.")
        runs = pd.DataFrame([table_row(run, result) for run, result in found])
        runs.to_csv(path, index=False)
        return runs, None

    def for_the_record(self, run: PlannedRun) -> dict[str, dict]:
        """The stored results of ``run`` under the configurations kept for the record
        (:data:`~anseg.study.plan.RECORD_CONFIGURATIONS`), by name, to set beside ours; never trained.

        A configuration is left out where the store lacks the run, or where
        this notebook runs that configuration itself (the column would repeat
        ours).
        """
        found = {config: self.stored_result(run, config) for config in RECORD_CONFIGURATIONS
                 if config != self.parameters["config"]}
        return {config: result for config, result in found.items() if result is not None}

    def model_file(self, result: dict) -> Path | None:
        """The model file of a result: the store's, else the committed one the figures render, else the shipped one.

        A result store travels without its models (``models/`` is not
        committed). Two kinds are: the pretrained models shipped with the
        package (those of the runs Tables I-III read) and, in
        ``results/models/``, the few others whose output a figure renders
        (``scripts/publish_models.py`` writes both). None when neither has it.
        """
        from anseg import pretrained

        for path in (self.store.model_path(result["key"]), self.results_dir / "models" / f"{result['key']}.pt"):
            if path.is_file():
                return path
        return pretrained.of_run(result["key"])

    def has_model(self, result: dict) -> bool:
        """Whether the model of a result is here: in the store, among the figures' committed models, or shipped."""
        return self.model_file(result) is not None

    def load_model(self, result: dict) -> Segmenter:
        """The model trained for ``result``, on the CPU (enough to segment a few meshes)."""
        path = self.model_file(result)
        if path is None:
            raise FileNotFoundError(
                f"the model of run {result['key']} is not on this machine (a result store travels without its models): "
                f"copy it to {self.store.model_path(result['key'])}, or delete {self.store.result_path(result['key'])} "
                "to train it here")
        return Segmenter.load(path)

    def test_meshes(self, dataset: str, category: str | None, split: int = 0) -> list:
        from anseg import datasets

        self._note_data(dataset)
        return datasets.load(dataset, category, "test", split, **(self.shape_options if dataset == "synthetic" else {}))

    def note_model(self, **model) -> None:
        """Name in the record the model the notebook segments with: ``pretrained=`` and ``card=``, ``file=`` or ``run=``."""
        self.record["model"] = model
        print("model:", json.dumps(model, default=str)[:400])

    def _note_data(self, dataset: str) -> None:
        """Add a data set the notebook read outside its planned runs to the record's ``data``."""
        if all(entry["dataset"] != dataset for entry in self.record["data"]):
            self.record["data"].append(self._data_record(dataset))

    def notice(self) -> str | None:
        """What a reader must know first about this run's data, or None."""
        if not self.synthetic:
            return None
        smoke = (f"Smoke settings (4 shapes, a tiny model, {self.parameters['epochs']} epochs): the numbers below mean "
                 "nothing. ") if self.smoke else ""
        return SYNTHETIC_NOTICE.format(smoke=smoke)

    def finish(self) -> Path:
        """Write the run record with its wall time to ``results/<notebook>.json``; returns its path."""
        self.record["wall_seconds"] = round(time.time() - self.started, 1)
        self.record["runs_read"] = runs_read = self._runs_read()
        path = self.results_dir / f"{self.name}.json"
        path.write_text(json.dumps(self.record, indent=1, default=str))
        print(f"{self.name}: {self.record['wall_seconds']:.0f} s wall time; record written to {path}")
        if runs_read["runs"]:
            print(f"the {runs_read['runs']} runs it read: trained on {runs_read['machines']}, CPU models "
                  f"{runs_read['cpu_models']}, "
                  f"code {runs_read['code_revisions']}, {runs_read['train_hours']:.2f} h of training in all")
        return path

    def machines(self) -> str:
        """For beside a table: the machines that trained the runs read so far, plainly when several, and their CPU
        models as the run records give them (:func:`cpu_of`), plainly where a record does not (the table may then
        mix CPUs without its records showing it)."""
        read = self._runs_read()
        machines, cpus = read["machines"], read["cpu_models"]
        listed = ", ".join(f"{machine} ({n} run{'s' if n > 1 else ''})" for machine, n in machines.items())
        if not machines:
            return "No stored run is read here."
        if len(machines) > 1:
            text = (f"**These runs mix machines:** {listed}. The same run can score differently on another device or "
                    "with other library versions; each run's machine is in the runs table.")
        else:
            text = f"Trained on one kind of machine: {listed}."
        text += " CPU models, from the run records: " + ", ".join(f"{cpu} ({n})" for cpu, n in cpus.items()) + "."
        known = [cpu for cpu in cpus if cpu != NOT_RECORDED and not cpu.startswith("GPU")]
        if len(known) > 1:
            text += " **These runs mix CPUs.**"
        if NOT_RECORDED in cpus:
            text += (" A record made before the CPU model was kept names only the architecture, so these runs may mix "
                     "CPUs unseen: docs/reproducibility.md has the evidence of which runs an AMD EPYC and which an "
                     "Intel Xeon trained.")
        return text

    def selection(self) -> str:
        """For beside a PSB table that reads splits other than 0: " " and how many of their test meshes the
        default's settings were chosen on (:mod:`anseg.study.selection`), split 0 named as the clean test; else ""."""
        from anseg.study import selection

        p = self.parameters
        if p["dataset"] != "psb" or "splits" not in p:
            return ""
        note = selection.psb_note(p["categories"], p["splits"])
        return f" **Selection:** {note}; split 0 alone is the clean test." if note else ""

    def summary(self) -> str:
        """The record in a few lines a reader takes in (Markdown): configuration, data, code, machine, versions."""
        env, p = self.record["environment"], self.parameters
        revision = (env.get("code_revision") or "not recorded")[:12]
        clean = {True: "", False: " (with uncommitted changes)", None: ""}[env.get("code_clean")]
        pinned = env.get("kernels", {})
        kernels = (f"kernels {pinned['pin']} (torch {pinned['torch']}, NumPy {pinned['numpy']}), {pinned['isa']}"
                   if pinned else f"torch kernels {env.get('torch_kernels', '?')}")
        machine = env.get("cuda") or f"{env.get('cpu_model', 'CPU')}, {env['cpus']} cores, {kernels}"
        data = ", ".join(d["dataset"] for d in self.record["data"])
        splits = f"; splits {', '.join(map(str, p['splits']))}" if "splits" in p else ""
        rows = [("configuration", f"`{p['config']}` ({p['epochs']} epochs, seed {p['seed']})"),
                ("data", f"{data}{splits}"), ("code", f"anseg {revision}{clean}; features {env.get('features', '?')}"),
                ("machine", f"{machine}; torch {env['torch']}, python {env['python']}"),
                ("record", f"`results/{self.name}.json` (wall time and the runs read, written when the notebook ends)")]
        return "| run record | |\n|---|---|\n" + "\n".join(f"| {name} | {value} |" for name, value in rows)

    def _runs_read(self) -> dict:
        """How many runs the notebook read, the machines and code revisions that trained them, and their training time."""
        from collections import Counter

        results = list(self.read.values())
        revisions = Counter(
            (r["environment"].get("code_revision") or "not recorded")[:12]
            + ("" if r["environment"].get("code_clean") in (True, None) else " (with uncommitted changes)")
            for r in results)
        return {"runs": len(results), "machines": dict(Counter(trained_on(r) for r in results)),
                "cpu_models": dict(Counter(cpu_of(r) for r in results)),
                "code_revisions": dict(revisions),
                "train_hours": round(sum(r.get("train_seconds", 0.0) for r in results) / 3600, 3)}

    def _record(self, parameters: dict) -> dict:
        import matplotlib
        import pandas

        import anseg

        return {
            "notebook": self.name,
            "parameters": parameters,
            "data": [self._data_record(name) for name in sorted({run.dataset for run in self.planned})],
            "seeds": {"training": self.train.seed, "clustering_and_collapse": SegmentConfig().seed},
            "configuration": parameters["config"],
            "settings": {"segment": asdict(SegmentConfig(**self.segment_options)),
                         "segment_overrides": self.segment_options, "train": asdict(self.train),
                         "synthetic_shapes": self.shape_options},
            "versions": {"anseg": anseg.__version__, "pandas": pandas.__version__, "matplotlib": matplotlib.__version__},
            "environment": environment(),
        }

    def _data_record(self, name: str) -> dict:
        """Where the data comes from: the generator's settings, or the data folder and the archives' sha256."""
        from anseg import datasets
        from anseg.datasets import synthetic
        from anseg.datasets.archive import KNOWN_ARCHIVES

        if name == "synthetic":
            return {"dataset": name, "location": "generated in memory by anseg.datasets.synthetic",
                    "n_shapes": self.shape_options.get("n_shapes", synthetic.N_SHAPES),
                    "generator_seed": synthetic.DEFAULT_SEED}
        root = datasets.data_root()
        return {"dataset": name, "data_root": os.path.relpath(root, REPO),  # relative: the same on every machine
                "archives_found (sha256 checked on read)": {a: h for a, h in KNOWN_ARCHIVES.items() if (root / a).is_file()},
                "extracted_folders_found (read as they are)": sorted(p.name for p in root.iterdir() if p.is_dir())}


def start(name: str, namespace: dict) -> NotebookRun:
    """Set up notebook ``name`` from the parameters its parameter cell left in ``namespace`` (its ``globals()``).

    Shows the synthetic-data notice where it applies and the run record in
    a few lines; the whole record (data, seeds, settings, versions, hardware)
    rides in that output's metadata (``anseg_record``) and in the record file.
    """
    import warnings

    from tqdm import TqdmWarning

    warnings.filterwarnings("ignore", category=TqdmWarning)  # without ipywidgets, tqdm's text bars are fine
    plan = PLANS.get(f"{name}.ipynb")
    names = [*COMMON["real"], *(plan.parameters["real"] if plan else {}), "output_dir"]  # the cell's order
    missing = [key for key in names if key not in namespace]
    if missing:
        raise ValueError(f"{name}: the parameter cell does not define {', '.join(missing)}")
    run = NotebookRun(name, {key: namespace[key] for key in names})
    from IPython import get_ipython
    from IPython.display import Markdown, display

    shown = "\n\n".join(filter(None, [run.notice(), run.summary()]))
    if get_ipython() is not None:
        display(Markdown(shown), metadata={"anseg_record": json.loads(json.dumps(run.record, default=str))})
    else:  # a plain script: text, not an object's repr
        print(shown)
    return run
