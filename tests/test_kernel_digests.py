"""One set of numbers on every x86-64 CPU: digests of a small training and of segmentations, recorded with their CPU.

The proof of :mod:`anseg.kernels`: a fixed training run (synthetic shapes, two
epochs) and segmentations with a shipped model, on one thread, digested to
sha256 (the trained weights, the labels). ``tests/data/kernel_digests.json``
holds the digests with the CPU models that produced or confirmed them. The test
recomputes them on whatever CPU runs the suite and fails on any difference,
naming the CPU that recorded them and this one. Running this file as a script
records this CPU as confirming them, and writes them only where none are stored
(``--force`` rewrites them after a deliberate change of code, features or pin).
"""

from __future__ import annotations

import anseg  # noqa: F401  first: the pin is set before NumPy and torch load

# isort: split
import hashlib
import json
import sys
from datetime import date
from pathlib import Path

import numpy as np
import pytest
import torch
from threadpoolctl import threadpool_limits

from anseg import datasets, kernels
from anseg.pipeline import SegmentConfig, Segmenter, segment
from anseg.study.store import cpu_model
from anseg.train import TrainConfig, fit

RECORD = Path(__file__).parent / "data" / "kernel_digests.json"
SHIPPED = "psb/Vase"  # quick (2.5 s on its first test mesh) and the shipped model whose labels moved most with the kernels


def sha(*arrays) -> str:
    digest = hashlib.sha256()
    for array in arrays:
        digest.update(np.ascontiguousarray(array).tobytes())
    return digest.hexdigest()


def one_thread(compute):
    """``compute()`` on one torch and one BLAS/OpenMP thread, as the study trains; the counts are restored after."""
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        with threadpool_limits(limits=1):
            return compute()
    finally:
        torch.set_num_threads(threads)


def synthetic_digests() -> dict[str, str]:
    """The fixed training run's weights and labels, and the shipped model's labels on a synthetic shape."""
    shapes = datasets.load("synthetic", category="figure", split="all", n_shapes=5, progress=False)
    model = fit(shapes[:3], shapes[0].label_names, SegmentConfig(cycles=2, clusters=4), TrainConfig(epochs=2, width=16),
                progress=False)
    state = model.network.state_dict()
    return {"training weights": sha(*(state[name].numpy() for name in sorted(state))),
            "training labels": sha(*(segment(item.mesh, model).labels.astype(np.int64) for item in shapes[3:])),
            f"{SHIPPED} on a synthetic shape": sha(segment(shapes[4].mesh, Segmenter.pretrained(SHIPPED)).labels
                                                   .astype(np.int64))}


def psb_digests(data_root) -> dict[str, str]:
    """The shipped model's labels on its run's first split-0 test mesh."""
    item = datasets.load("psb", SHIPPED.split("/")[1], "test", 0, root=data_root, progress=False)[0]
    return {f"{SHIPPED} on PSB {item.name}": sha(segment(item.mesh, Segmenter.pretrained(SHIPPED)).labels.astype(np.int64))}


def differences(stored: dict, computed: dict[str, str]) -> list[str]:
    """Each digest that differs from the stored one, as a sentence naming both CPUs."""
    cpus, here = ", ".join(stored["cpus"]), f"{cpu_model()}, kernels {kernels.in_force()['pin']}"
    return [f"{name}: {digest[:12]} here ({here}), {stored['digests'][name][:12]} on {cpus}"
            for name, digest in computed.items() if stored["digests"].get(name) != digest]


def test_a_fixed_training_and_a_shipped_model_give_the_recorded_digests_on_this_cpu():
    stored = json.loads(RECORD.read_text())
    assert stored["pin"] == kernels.PIN_NAME, "the digests were recorded under another pin: rerun this file as a script"
    assert differences(stored, one_thread(synthetic_digests)) == []


@pytest.mark.realdata
def test_a_shipped_model_labels_a_psb_mesh_as_recorded_on_this_cpu(data_root):
    stored = json.loads(RECORD.read_text())
    assert differences(stored, one_thread(lambda: psb_digests(data_root))) == []


def test_a_digest_that_differs_names_both_cpus():
    stored = {"cpus": ["CPU A"], "digests": {"x": "0" * 64}}
    assert differences(stored, {"x": "0" * 64}) == []
    assert differences(stored, {"x": "1" * 64})[0].startswith(f"x: 111111111111 here ({cpu_model()}")
    assert differences(stored, {"x": "1" * 64})[0].endswith("000000000000 on CPU A")


def main(argv: list[str]) -> int:
    from anseg.datasets.archive import data_root

    computed = {**one_thread(synthetic_digests), **one_thread(lambda: psb_digests(data_root(None)))}
    here = f"{cpu_model()} ({kernels.isa_level()}), {date.today().isoformat()}"
    stored = json.loads(RECORD.read_text()) if RECORD.is_file() else None
    if stored and "--force" not in argv:
        if stored["pin"] != kernels.PIN_NAME or (problems := differences(stored, computed)):
            print("the digests differ from the stored ones:", *(problems if stored["pin"] == kernels.PIN_NAME
                                                                else [f"pin {stored['pin']}"]), sep="\n  ")
            return 1
        if not any(entry.startswith(f"{cpu_model()} (") for entry in stored["cpus"]):
            stored["cpus"].append(here)
    else:
        stored = {"pin": kernels.PIN_NAME, "cpus": [here], "digests": computed}
    RECORD.write_text(json.dumps(stored, indent=1) + "\n")
    print(f"{RECORD.name}: {len(computed)} digests, recorded or confirmed on {', '.join(stored['cpus'])}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
