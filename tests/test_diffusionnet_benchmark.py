"""The DiffusionNet rerun's checkpoint (benchmarks/diffusionnet.py): a run stopped with its session resumes to the
same weights. The authors' network is not needed: the checkpoint holds any torch model, optimiser and schedule."""

from __future__ import annotations

import importlib.util
from argparse import Namespace

import numpy as np
import pytest
import torch

from anseg.study.store import REPO

spec = importlib.util.spec_from_file_location("diffusionnet_benchmark", REPO / "benchmarks" / "diffusionnet.py")
benchmark = importlib.util.module_from_spec(spec)
spec.loader.exec_module(benchmark)

DATA = [(torch.randn(16, 4), torch.randint(0, 3, (16,))) for _ in range(5)]


def args(folder, **changed) -> Namespace:
    return Namespace(**{"dataset": "psb", "split": 0, "epochs": 6, "input": "xyz", "seed": 0, "checkpoint": folder,
                        **changed})


def train(arguments, stop_after: int | None = None):
    """The benchmark's loop in small: a model, Adam, a step schedule, torch's and numpy's generators, a checkpoint
    after every epoch; ``stop_after`` epochs, as a session that ends."""
    torch.manual_seed(0)
    rotation = np.random.RandomState(0)
    model = torch.nn.Sequential(torch.nn.Linear(4, 8), torch.nn.Dropout(0.5), torch.nn.Linear(8, 3))
    optimizer = torch.optim.Adam(model.parameters(), lr=1e-2)
    scheduler = torch.optim.lr_scheduler.StepLR(optimizer, step_size=2, gamma=0.5)
    state = benchmark.Checkpoint(arguments, "Hand", model, optimizer, scheduler, rotation)
    first, spent = state.resume()
    for epoch in range(first, arguments.epochs if stop_after is None else stop_after):
        for i in torch.randperm(len(DATA)).tolist():
            x, y = DATA[i]
            x = x + float(rotation.rand())  # the numpy generator is used as the xyz rotations use it
            loss = torch.nn.functional.cross_entropy(model(x), y)
            optimizer.zero_grad()
            loss.backward()
            optimizer.step()
        scheduler.step()
        state.save(epoch + 1, spent + (epoch + 1 - first))  # a second an epoch
    return model, first, state


def test_a_stopped_run_resumes_to_the_weights_of_the_uninterrupted_one(tmp_path):
    whole, _, _ = train(args(None))
    train(args(tmp_path), stop_after=2)
    resumed, first, state = train(args(tmp_path))
    assert first == 2 and state.path.is_file()
    for a, b in zip(whole.state_dict().values(), resumed.state_dict().values()):
        assert torch.equal(a, b)
    assert torch.load(state.path, weights_only=False)["train_s"] == pytest.approx(6.0)  # every session's seconds


def test_a_checkpoint_of_other_settings_is_not_resumed_and_a_partial_write_leaves_the_last_whole_one(tmp_path):
    train(args(tmp_path), stop_after=2)
    _, first, _ = train(args(tmp_path, seed=1), stop_after=1)  # another seed: another file, from the start
    assert first == 0
    _, first, state = train(args(tmp_path, epochs=7), stop_after=0)  # the same file name, other settings
    assert first == 0
    state.path.with_suffix(".partial").write_bytes(b"cut off")  # a run stopped while writing
    _, first, _ = train(args(tmp_path), stop_after=0)
    assert first == 2
