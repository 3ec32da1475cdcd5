"""What an experiment is and where its result is kept.

* :class:`Experiment` and its key: one trained-and-evaluated configuration,
  keyed by everything that decides its result.
* :class:`ResultStore`: ``<root>/results/runs/<key>.json`` and
  ``<root>/models/<key>.pt``, written atomically by the process that asked
  for the run (never by a worker, so workers need no file system shared
  with it), with a resumable checkpoint beside the model while training.
* :func:`environment`: what every stored result records of the machine and the code.
"""

from __future__ import annotations

import hashlib
import json
import os
import platform
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path

import numpy as np
import torch

from anseg import features, kernels
from anseg.cache import atomic_write
from anseg.model import RETIRED
from anseg.pipeline import SEGMENT_SETTINGS_ADDED_LATER, SegmentConfig
from anseg.study import releases
from anseg.train import TRAIN_SETTINGS_ADDED_LATER, TrainConfig

REPO = Path(__file__).resolve().parents[2]

# Fields of SegmentConfig ("segment") and TrainConfig ("train") introduced after results were stored, with
# the value the older results ran with: at that value a field stays out of the key.
SETTINGS_ADDED_LATER = {"segment": SEGMENT_SETTINGS_ADDED_LATER, "train": TRAIN_SETTINGS_ADDED_LATER}
# The feature code every stored result ran with: its version and FeatureSettings' defaults. A result computed
# from other features has other keys, so no stored result or model is reused across a change of features
# (a version that computes the same features on the benchmark meshes is no change: features.comparable).
FEATURES_OF_STORED_RESULTS = {"version": 1, "sdf_rays": 16, "sdf_cone_degrees": 120.0, "agd_sources": 64,
                              "smooth_radii": (0.03, 0.1, 0.3)}


@dataclass
class Experiment:
    """One trained-and-evaluated configuration: what a table cell is made of."""

    dataset: str
    category: str | None
    split_index: int = 0
    segment: SegmentConfig = field(default_factory=SegmentConfig)
    train: TrainConfig = field(default_factory=TrainConfig)

    def key(self, dataset_options: dict | None = None) -> str:
        """A short hash of everything that decides the result, data set options (e.g. ``n_shapes``) included.

        Settings added after results were stored leave the key alone at their
        default (:data:`SETTINGS_ADDED_LATER`), so those results keep their keys;
        so does the feature code they ran with (:data:`FEATURES_OF_STORED_RESULTS`).
        """
        keyed = {part: {k: v for k, v in asdict(config).items() if SETTINGS_ADDED_LATER[part].get(k, object()) != v}
                 for part, config in (("segment", self.segment), ("train", self.train))}
        if features.comparable(code := features.code()) != features.comparable(FEATURES_OF_STORED_RESULTS):
            keyed["features"] = code
        text = json.dumps({"dataset": self.dataset, "category": self.category, "split": self.split_index, **keyed,
                           **({"options": dataset_options} if dataset_options else {})}, sort_keys=True)
        return hashlib.sha256(text.encode()).hexdigest()[:16]


def recorded_settings(record: dict) -> tuple[SegmentConfig, TrainConfig]:
    """The settings a stored result ran with, as today's classes.

    A setting added since takes the value the older results ran with
    (:data:`SETTINGS_ADDED_LATER`), a retired switch is dropped where it was
    off (:data:`anseg.model.RETIRED`), and lists come back as tuples. A
    setting this code no longer has in any other form is a ValueError: such a
    result replays at its own revision only.
    """
    configs = []
    for part, config_class in (("segment", SegmentConfig), ("train", TrainConfig)):
        known = {f.name: f for f in fields(config_class)}
        values = {**{k: v for k, v in SETTINGS_ADDED_LATER[part].items() if k in known}, **record[part]}
        retired_on = {k: v for k, v in values.items() if k in RETIRED and v != RETIRED[k]}
        unknown = sorted(set(values) - set(known) - set(RETIRED))
        if retired_on or unknown:
            raise ValueError(f"{record.get('key')}: settings this code no longer has "
                             f"({retired_on or unknown}); replay it at its own revision")
        defaults = config_class()
        configs.append(config_class(**{k: tuple(v) if isinstance(getattr(defaults, k), tuple) else v
                                       for k, v in values.items() if k in known}))
    return configs[0], configs[1]


def environment() -> dict:
    """Versions, hardware (and the torch threads a replay needs), the kernels in force (:func:`anseg.kernels.in_force`),
    the locked releases (:func:`anseg.study.releases.record`), the code revision, the features' fingerprint and the
    date (UTC), kept with every result."""
    from datetime import datetime, timezone

    import sklearn
    import trimesh

    return {
        "python": platform.python_version(), "torch": torch.__version__, "numpy": np.__version__,
        "trimesh": trimesh.__version__, "scikit-learn": sklearn.__version__,
        "machine": platform.machine(), "processor": platform.processor() or platform.machine(),
        "torch_threads": torch.get_num_threads(),
        "torch_kernels": torch.backends.cpu.get_cpu_capability(),  # another instruction set rounds otherwise
        **hardware(), "kernels": kernels.in_force(), "releases": releases.record(),
        **code_revision(), "features": features.fingerprint(),
        "date": datetime.now(timezone.utc).isoformat(timespec="seconds"),
    }


def hardware() -> dict:
    """The device this process computes on, as a record keeps it: the CPU count and model, and the GPU (None on CPU).

    The model matters even between CPUs of one instruction set (AMD EPYC,
    Intel Xeon): see :func:`cpu_model`.
    """
    return {"cpus": os.cpu_count(), "cpu_model": cpu_model(),
            "cuda": torch.cuda.get_device_name(0) if torch.cuda.is_available() else None}


def cpu_model() -> str:
    """The CPU's model name, from ``/proc/cpuinfo`` (``platform.processor()`` where that file is absent).

    Two CPUs with the same instruction set can still round a float kernel
    differently, and the default's weighted collapse turns a last-digit
    difference into another hierarchy, so a run replays bit for bit only on
    the CPU model that trained it.
    """
    return kernels.cpu_info("model name") or platform.processor() or platform.machine()


def code_revision(root: Path = REPO) -> dict:
    """The git commit the package runs from and whether its code differs from it (None for both outside a checkout).

    ``code_clean`` looks at the tracked files of the package and its build
    file only: a study writes its results into the same checkout, and those
    writes change no code.
    """
    import subprocess

    def git(*args: str) -> str | None:
        try:
            done = subprocess.run(["git", "-C", str(root), *args], capture_output=True, text=True, timeout=30)
        except (OSError, subprocess.TimeoutExpired):
            return None
        return done.stdout.strip() if done.returncode == 0 else None

    revision = git("rev-parse", "HEAD")
    changes = git("status", "--porcelain", "--untracked-files=no", "--", "anseg", "pyproject.toml") if revision else None
    return {"code_revision": revision, "code_clean": None if changes is None else not changes}


def trained_on(result: dict) -> str:
    """The machine a stored result was trained on: its GPU, else its CPU model and count ("CPU" where the record
    predates the model) and the kernel pin it ran under (where the record names one: records made before the pin
    ran each library's own kernels), since a notebook may read results made elsewhere."""
    env = result["environment"]
    pin = f", kernels {env['kernels']['pin']}" if "kernels" in env else ""
    return env["cuda"] or f"{env.get('cpu_model', 'CPU')}, {env['cpus']} cores{pin}"


NOT_RECORDED = "CPU model not recorded"


def cpu_of(result: dict) -> str:
    """The CPU model that trained a stored result, from its record's ``cpu_model`` (else a ``processor`` that names
    more than the architecture); "GPU: <name>" for a GPU run; :data:`NOT_RECORDED` where the record does not say."""
    env = result.get("environment") or {}
    if env.get("cuda"):
        return f"GPU: {env['cuda']}"
    model = env.get("cpu_model") or env.get("processor")
    return model if model and model != env.get("machine") else NOT_RECORDED


class ResultStore:
    """Results (under ``results``, relative to the root) and models (under ``models``); every write is atomic."""

    def __init__(self, root: str | os.PathLike, results: str = "results/runs"):
        self.root = Path(root)
        self.results = self.root / results

    def result_path(self, key: str) -> Path:
        return self.results / f"{key}.json"

    def model_path(self, key: str) -> Path:
        return self.root / "models" / f"{key}.pt"

    def checkpoint_path(self, key: str) -> Path:
        return self.model_path(key).with_suffix(".ckpt")

    def get(self, key: str) -> dict | None:
        """The stored result of ``key``, or None."""
        path = self.result_path(key)
        return json.loads(path.read_text()) if path.is_file() else None

    def put(self, result: dict, model: bytes | None = None, model_key: str | None = None) -> dict:
        """Store a result and its model file's bytes (under ``model_key``, default the result's key).

        The model goes first, so a stored result always has its model.
        """
        model_key = model_key or result["key"]
        if model is not None:
            atomic_write(self.model_path(model_key), lambda tmp: tmp.write_bytes(model))
            self.checkpoint_path(model_key).unlink(missing_ok=True)
        text = json.dumps(result, indent=1)
        atomic_write(self.result_path(result["key"]), lambda tmp: tmp.write_text(text))
        return json.loads(text)  # the form a stored result is read back in

