"""Replay stored runs: retrain each from the code revision it recorded and compare the accuracy to the last digit.

    python scripts/replay_run.py results/runs/<key>.json [...] [--data DIR] [--keep] [--csv FILE]
    python scripts/replay_run.py --sample 5 [--seed 0] [--among results/table1_psb_runs.csv] [--csv FILE]
    python scripts/replay_run.py results/superseded/<machine>/<key>.json [...] --retrained results/runs [--csv FILE]
    python scripts/replay_run.py --sample 2 --among A.csv --among B.csv --at REV --at REV [...] [--csv FILE]

``--sample N`` draws the runs itself from the keys of a runs table (Table
I's by default; N from each table where ``--among`` is given more than once),
among those that can be replayed here, one revision after another (a
revision's runs drawn by ``--seed``) so that the sample spans the revisions
the table read; ``--csv`` keeps one line per replay.

The run's recorded revision is checked out into a temporary git worktree and
the experiment (the recorded data set, category, split and settings) is
trained and evaluated there, in a fresh process with the recorded number of
torch threads (one when the record predates that field) and an empty feature
cache (older revisions key it without the code that fills it), against the
same Python environment. The replay holds when the new run has the same key and
the same accuracy (Eq. 5, unit area, and raw area and per face) as the
stored one, float for float; exit status 0 then, 1 when it differs, 2 when
the run cannot be replayed here (no revision recorded, uncommitted changes
at training time, trained on a GPU, or the revision is not in this clone).

``--retrained DIR`` compares instead with a retraining already stored in DIR
under the same key (one the study's planner made on another machine, say, at
the same revision), so that a whole table retrained elsewhere is compared
run by run without training it a third time.

``--at REV`` (given once per revision) measures the drift between code
revisions instead: each run is trained at every REV, on this machine, and
the accuracies are set side by side; revisions whose package folder is the
same git tree train the same code, so each tree is trained once and its
number stands for all of them. Exit status 0 when every run gives the same
accuracy at every revision, 1 when some differ, 2 when one cannot be trained.

Replay needs the package's dependencies at the versions the record names;
where they differ, it says so before training, since torch's kernels may
round differently from one version to the next.
"""

from __future__ import annotations

import anseg  # noqa: F401  first: importing anseg pins the float kernels before NumPy and torch load

# isort: split
import argparse
import csv
import json
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent

# runs in the worktree: the recorded experiment, trained and evaluated by the code of that revision
RETRAIN = """
import json, sys
import torch
try:
    from anseg.study.runner import train_and_evaluate
    from anseg.study.store import Experiment
except ImportError:  # a revision from before the study had a folder of its own
    from anseg.experiments import Experiment, train_and_evaluate
from anseg.pipeline import SegmentConfig
from anseg.train import TrainConfig
run = json.load(sys.stdin)
torch.set_num_threads(run["threads"])
experiment = Experiment(run["dataset"], run["category"], run["split_index"], SegmentConfig(**run["segment"]),
                        TrainConfig(**run["train"]))
result, _ = train_and_evaluate(experiment, run["dataset_options"], run["root"])
print(json.dumps({"key": result["key"], "accuracy": result["accuracy"], "train_seconds": result["train_seconds"]}))
"""


def why_not(run: dict) -> str | None:
    """Why the stored ``run`` cannot be replayed on this machine, or None."""
    env = run.get("environment", {})
    if not env.get("code_revision"):
        return "the run records no code revision"
    if env.get("code_clean") is not True:
        return f"the run was trained with uncommitted changes on top of {env['code_revision'][:12]}"
    if env.get("cuda"):
        return f"the run was trained on a GPU ({env['cuda']}); a CPU run does not round the same way"
    return None


def version_differences(env: dict) -> list[str]:
    """The recorded library versions and CPU model that differ from this environment's."""
    import numpy
    import sklearn
    import torch
    import trimesh

    from anseg.study.store import cpu_model

    here = {"torch": torch.__version__, "numpy": numpy.__version__, "trimesh": trimesh.__version__,
            "scikit-learn": sklearn.__version__, "cpu_model": cpu_model()}
    return [f"{name} {env[name]} recorded, {version} here" for name, version in here.items()
            if env.get(name) not in (None, version)]


def sample(runs: dict[str, dict], n: int, seed: int) -> list[str]:
    """``n`` keys of ``runs`` (key: stored record) that can be replayed here, one revision after another, each
    revision's drawn in a seeded order, so that a small sample spans the revisions."""
    import random

    by_revision: dict[str, list[str]] = {}
    for key in sorted(runs):
        if why_not(runs[key]) is None:
            by_revision.setdefault(runs[key]["environment"]["code_revision"], []).append(key)
    rng = random.Random(seed)
    queues = [rng.sample(keys, len(keys)) for _, keys in sorted(by_revision.items())]
    drawn = []
    while len(drawn) < n and any(queues):
        drawn += [queue.pop(0) for queue in queues if queue][: n - len(drawn)]
    return drawn


def replay(run: dict, root: str | None = None, keep: bool = False, revision: str | None = None) -> dict:
    """Retrain ``run`` at its recorded revision (or at ``revision``); the new run's key, accuracy and training
    seconds."""
    revision = revision or run["environment"]["code_revision"]
    worktree = Path(tempfile.mkdtemp(prefix="anseg-replay-")) / "tree"
    added = subprocess.run(["git", "-C", str(REPO), "worktree", "add", "--detach", str(worktree), revision],
                           capture_output=True, text=True)
    if added.returncode != 0:
        raise LookupError(f"revision {revision[:12]} cannot be checked out here: {added.stderr.strip()}")
    try:
        threads = run["environment"].get("torch_threads", 1)
        job = {**{k: run[k] for k in ("dataset", "category", "split_index", "segment", "train")},
               "dataset_options": run.get("dataset_options", {}), "root": root, "threads": threads}
        # an empty feature cache of its own: an older revision keys the cache without the code that computes it,
        # so a shared cache could hand it features of another revision (as it did to f28ec7061d9ca1da's first replays)
        environment = {**os.environ, "PYTHONPATH": str(worktree), "OMP_NUM_THREADS": str(threads),
                       "ANSEG_CACHE": str(worktree.parent / "cache")}
        done = subprocess.run([sys.executable, "-c", RETRAIN], input=json.dumps(job), cwd=worktree, env=environment,
                              capture_output=True, text=True)
        if done.returncode != 0:
            raise RuntimeError(f"the replay failed at {revision[:12]}: {done.stderr.strip().splitlines()[-1]}")
        return json.loads(done.stdout.strip().splitlines()[-1])
    finally:
        if not keep:
            subprocess.run(["git", "-C", str(REPO), "worktree", "remove", "--force", str(worktree)], capture_output=True)
            shutil.rmtree(worktree.parent, ignore_errors=True)


def stored(path: Path) -> tuple[dict | None, dict | None]:
    """The run stored at ``path`` if it can be trained again here, else None and its --csv line saying why not."""
    try:
        run = json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        print(f"replay_run: cannot read {path}: {exc}", file=sys.stderr)
        return None, {"key": path.stem, "holds": None, "why": str(exc)}
    if reason := why_not(run):
        print(f"replay_run: cannot replay {path.name}: {reason}", file=sys.stderr)
        return None, {"key": path.stem, "holds": None, "why": reason}
    return run, None


def code_tree(revision: str) -> tuple[str, str]:
    """``revision`` in full and the git tree of its package folder (two revisions with one tree train the same code)."""
    trees = [subprocess.run(["git", "-C", str(REPO), "rev-parse", "--verify", "--quiet", f"{revision}^{{commit}}{path}"],
                            capture_output=True, text=True) for path in ("", ":anseg")]
    if any(done.returncode != 0 for done in trees):
        raise LookupError(f"revision {revision} is not in this clone")
    return trees[0].stdout.strip(), trees[1].stdout.strip()


def across(path: Path, root: str | None, keep: bool, revisions: list[str]) -> list[dict]:
    """Train the run stored at ``path`` at each of ``revisions`` here (once per package tree) and print the
    accuracies side by side; one line per revision for --csv (``holds``: the same accuracy at every revision)."""
    run, refused = stored(path)
    if refused:
        return [refused]
    by_tree: dict[str, dict] = {}
    trained: list[tuple[str, str]] = []  # (revision, its package tree), in the order asked
    print(f"{run['dataset']} {run['category']} split {run['split_index']} (stored {run['accuracy']['unit_area']!r}, "
          f"at {run['environment']['code_revision'][:12]})")
    for wanted in revisions:
        try:
            revision, tree = code_tree(wanted)
            if tree not in by_tree:
                by_tree[tree] = replay(run, root, keep, revision)
        except (LookupError, RuntimeError) as exc:
            print(f"replay_run: {exc}", file=sys.stderr)
            return [{"key": run["key"], "holds": None, "why": str(exc)}]
        again = by_tree[tree]
        print(f"  at {revision[:12]} (package tree {tree[:12]}): {again['accuracy'].get('unit_area')!r}"
              + ("" if again["key"] == run["key"] else " (another key)"))
        trained.append((revision, tree))
    same = len({(again["key"], json.dumps(again["accuracy"], sort_keys=True)) for again in by_tree.values()}) == 1
    print("the same at every revision" if same else "the revisions DIFFER")
    machine = here()
    return [{**csv_line(run, by_tree[tree], machine, same), "at": revision[:12], "code_tree": tree[:12]}
            for revision, tree in trained]


def retrained_record(run: dict, folder: Path) -> dict:
    """The retraining of ``run`` stored in ``folder`` under its key, at its revision, as ``replay`` gives one."""
    path = folder / f"{run['key']}.json"
    try:
        again = json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise LookupError(f"no retraining of {run['key']} in {folder}: {exc}") from exc
    if again.get("environment", {}).get("code_revision") != run["environment"]["code_revision"]:
        raise LookupError(f"{path} was trained at another revision, so it does not replay {run['key']}")
    return again


def compare(path: Path, root: str | None, keep: bool, retrained: Path | None = None) -> dict:
    """Replay the run stored at ``path`` (or read its retraining from ``retrained``) and print the comparison; its
    line for --csv (``holds``: True, False, or None where it cannot be replayed here, with the reason)."""
    run, refused = stored(path)
    if refused:
        return refused
    if retrained is None:
        for difference in version_differences(run["environment"]):
            print(f"replay_run: warning: {difference}", file=sys.stderr)
    try:
        again = retrained_record(run, retrained) if retrained else replay(run, root, keep)
    except (LookupError, RuntimeError) as exc:
        print(f"replay_run: {exc}", file=sys.stderr)
        return {"key": path.stem, "holds": None, "why": str(exc)}
    from anseg.study.store import trained_on

    same = again["key"] == run["key"] and again["accuracy"] == run["accuracy"]
    print(f"{run['dataset']} {run['category']} split {run['split_index']} at {run['environment']['code_revision'][:12]}")
    for metric, value in run["accuracy"].items():
        print(f"  {metric:<10} stored {value!r:<22} replayed {again['accuracy'].get(metric)!r}")
    print(f"  training: stored {run['train_seconds']:.0f} s, replayed {again['train_seconds']:.0f} s")
    print("replay holds" if same else ("replay DIFFERS" + ("" if again["key"] == run["key"] else " (another key)")))
    return csv_line(run, again, trained_on(again) if retrained else here(), same)


def csv_line(run: dict, again: dict, replayed_on: str, holds: bool) -> dict:
    """The --csv line that sets the stored ``run`` beside ``again``, its retraining on the machine ``replayed_on``."""
    from anseg.study.store import trained_on

    return {"key": run["key"], "category": run["category"], "split": run["split_index"],
            "revision": run["environment"]["code_revision"][:12], "stored": run["accuracy"]["unit_area"],
            "replayed": again["accuracy"].get("unit_area"), "trained_on": trained_on(run),
            "replayed_on": replayed_on, "holds": holds, "why": ""}


def here() -> str:
    """This machine, named as a stored run names the one it was trained on."""
    from anseg.study.store import hardware, trained_on

    return trained_on({"environment": hardware()})


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("results", type=Path, nargs="*", help="stored results, results/runs/<key>.json")
    parser.add_argument("--sample", type=int, metavar="N", help="replay N runs drawn from --among's keys instead")
    parser.add_argument("--among", type=Path, action="append",
                        help="a runs table --sample draws from, N runs from each (default: Table I's)")
    parser.add_argument("--seed", type=int, default=0, help="seed of --sample's draw (default: 0)")
    parser.add_argument("--csv", type=Path, help="write one line per run: key, revision, stored and replayed accuracy, "
                                                   "the machines of both")
    parser.add_argument("--data", help="data root (default: $ANSEG_DATA)")
    parser.add_argument("--keep", action="store_true", help="keep the worktree of the recorded revision")
    parser.add_argument("--retrained", type=Path, metavar="DIR",
                        help="compare with the retraining stored in DIR under each run's key instead of training")
    parser.add_argument("--at", action="append", metavar="REV",
                        help="train each run at REV here instead (give it once per revision) to measure their drift")
    args = parser.parse_args(argv)
    if args.at and args.retrained:
        parser.error("--at trains at other revisions; --retrained reads a retraining: give one of them")
    paths = list(args.results)
    if args.sample is not None:
        store = REPO / "results" / "runs"
        for table in args.among or [REPO / "results" / "table1_psb_runs.csv"]:
            try:
                with open(table, newline="") as handle:
                    keys = sorted({row["key"] for row in csv.DictReader(handle)})
            except (OSError, KeyError) as exc:
                parser.error(f"--among {table}: no runs table with a key column ({exc})")
            runs = {key: json.loads((store / f"{key}.json").read_text()) for key in keys
                    if (store / f"{key}.json").is_file() and store / f"{key}.json" not in paths}
            paths += [store / f"{key}.json" for key in sample(runs, args.sample, args.seed)]
    if not paths:
        parser.error("give stored results, or --sample N")
    if args.at:
        rows = [row for path in paths for row in across(path, args.data, args.keep, args.at)]
    else:
        rows = [compare(path, args.data, args.keep, args.retrained) for path in paths]
    if args.csv:
        columns = ["key", "category", "split", "revision", "stored", "replayed", "trained_on", "replayed_on", "holds",
                   "why"]
        if args.at:
            columns[5:5] = ["at", "code_tree"]
        with open(args.csv, "w", newline="") as handle:
            writer = csv.DictWriter(handle, fieldnames=columns)
            writer.writeheader()
            writer.writerows({column: row.get(column, "") for column in columns} for row in rows)
    if any(row["holds"] is None for row in rows):
        return 2
    return 0 if all(row["holds"] for row in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
