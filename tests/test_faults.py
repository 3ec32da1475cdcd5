"""What must survive a crash: a training run killed mid-epoch resumes to the same model and keeps its seconds;
concurrent cache writers."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest
import torch

from anseg import cache, datasets
from anseg.pipeline import SegmentConfig
from anseg.train import TrainConfig, fit, fit_and_time

# every epoch averaged (average_last): the checkpoint carries a partial sum of weights
SEGMENT, TRAIN = {"cycles": 2, "clusters": 4}, {"epochs": 6, "width": 16, "recollapse_every": 4, "average_last": 6}
TRAINING = textwrap.dedent(f'''
    import sys, torch
    torch.set_num_threads(1)
    from anseg import datasets
    from anseg.pipeline import SegmentConfig
    from anseg.train import TrainConfig, fit
    meshes = datasets.load("synthetic", "figure", "train", n_shapes=8, progress=False)
    fit(meshes, meshes[0].label_names, SegmentConfig(**{SEGMENT!r}), TrainConfig(**{TRAIN!r}), checkpoint=sys.argv[1],
        progress=False)
''')


def checkpoint_epoch(path) -> int:
    try:
        return torch.load(path, weights_only=True)["epoch"]
    except Exception:  # not written yet, or being renamed into place
        return 0


@pytest.mark.slow
def test_a_run_killed_mid_epoch_resumes_to_the_same_model(tmp_path):
    torch.set_num_threads(1)
    checkpoint = tmp_path / "run.ckpt"
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    child = subprocess.Popen([sys.executable, "-c", TRAINING, str(checkpoint)], env=env)
    try:
        deadline = time.time() + 300
        while checkpoint_epoch(checkpoint) < 1 and time.time() < deadline and child.poll() is None:
            time.sleep(0.02)
        child.send_signal(signal.SIGKILL)  # mid-epoch 2, between two rebuilds of the hierarchy
    finally:
        child.wait()
    killed_at = checkpoint_epoch(checkpoint)
    assert 1 <= killed_at < 6, "the run was not killed in the middle"
    meshes = datasets.load("synthetic", "figure", "train", n_shapes=8, progress=False)
    segment, train = SegmentConfig(**SEGMENT), TrainConfig(**TRAIN)
    killed_after = torch.load(checkpoint, weights_only=True)["seconds_spent"][0]
    resumed, seconds, _ = fit_and_time(meshes, meshes[0].label_names, segment, train, checkpoint=checkpoint, progress=False)
    straight = fit(meshes, meshes[0].label_names, segment, train, progress=False)
    for a, b in zip(straight.network.state_dict().values(), resumed.network.state_dict().values()):
        assert torch.equal(a, b)
    assert seconds > killed_after > 0  # the record states the killed session's seconds too


@pytest.mark.slow
def test_two_processes_filling_the_same_cache_entry_both_succeed(tmp_path):
    script = textwrap.dedent('''
        import numpy as np, trimesh
        from anseg import features
        from anseg.mesh import Mesh
        sphere = trimesh.creation.icosphere(subdivisions=4)
        x = features.compute(Mesh(sphere.vertices * [2.0, 1.0, 1.0], sphere.faces))
        print(float(np.abs(x).sum()))
    ''')
    env = {**os.environ, "ANSEG_CACHE": str(tmp_path), "OMP_NUM_THREADS": "1"}
    runs = [subprocess.Popen([sys.executable, "-c", script], env=env, stdout=subprocess.PIPE, text=True) for _ in range(2)]
    outputs = [run.communicate(timeout=300)[0] for run in runs]
    assert [run.returncode for run in runs] == [0, 0]
    assert outputs[0] == outputs[1]
    entries = list((tmp_path / "features").iterdir())
    assert len(entries) == 1 and entries[0].suffix == ".npy"  # one entry, no temporary file left behind
    assert cache.read_checked_array(entries[0], np.load(entries[0]).shape) is not None  # its checksum holds
