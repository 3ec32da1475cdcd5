"""Peers measured here: DiffusionNet rerun on our data, read from the outputs its script stores.

``benchmarks/diffusionnet.py`` trains DiffusionNet (Sharp et al. 2022) from a
clone of the authors' repository, with their settings, on exactly our data,
split and metric, and writes one JSON per run (``--json``) with its settings,
its accuracies and the machine's record. A peer's number is shown only where
such an output is stored under ``results/peers/``: a number nobody can trace
to a run does not enter a table or a sentence. So the column holds the
categories run so far and no more, and its mean only when all 16 PSB
categories are there (the mean of a subset would not be Table I's mean).

Each value is the unit-area Eq. 5 (the mean of the per-mesh accuracies, our
primary figure), of one run with one seed; the source says where it ran.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

from anseg.study.store import NOT_RECORDED, REPO

PEERS = REPO / "results" / "peers"


@dataclass(frozen=True)
class PeerRun:
    """One stored rerun of a peer: its method's name, what it measured (a PSB category or a data set), where."""

    method: str  # e.g. "DiffusionNet (hks)"
    dataset: str  # "psb" or "human_seg"
    key: str  # the PSB category, or the data set's name for one without categories
    split: int
    unit_area: float
    cpu: str  # the CPU model or the device, as the run's record names it
    path: Path

    @property
    def source(self) -> str:
        return (f"{self.method} from the authors' repository, run by this project on its data, split {self.split} "
                f"and metric (Eq. 5, unit area), one seed, on {self.cpu}: {self.path.relative_to(REPO)}")


def _runs_in(path: Path) -> list[PeerRun]:
    stored = json.loads(path.read_text())
    settings, environment = stored["settings"], stored.get("environment", {})
    dataset = settings.get("dataset", "psb")  # the first outputs predate the human set's option: PSB
    cpu = ("a CUDA GPU" if settings.get("device") == "cuda" or environment.get("cuda")
           else environment.get("cpu_model") or f"a CPU ({NOT_RECORDED})")
    return [PeerRun(f"DiffusionNet ({settings['input']})", dataset, row["category"], settings.get("split", 0),
                    row["unit_area"], cpu, path) for row in stored["categories"]]


def stored_runs(folder: Path = PEERS) -> list[PeerRun]:
    """Every peer run stored in ``folder``; two runs of one method on the same category and split is an error
    (which would a table show?), said in one line."""
    runs = [run for path in sorted(folder.glob("*.json")) for run in _runs_in(path)]
    seen = {}
    for run in runs:
        other = seen.setdefault((run.method, run.dataset, run.key, run.split), run)
        if other is not run:
            raise ValueError(f"{other.path.name} and {run.path.name} both hold {run.method} on {run.key}, "
                             f"split {run.split}: keep one")
    return runs


def measured_here(dataset: str, split: int = 0, folder: Path = PEERS) -> dict[str, dict[str, PeerRun]]:
    """By method: its stored runs on ``dataset`` (``"psb"``: by category; ``"human_seg"``: under that name) and split."""
    methods: dict[str, dict[str, PeerRun]] = {}
    for run in stored_runs(folder):
        if run.dataset == dataset and run.split == split:
            methods.setdefault(run.method, {})[run.key] = run
    return methods
