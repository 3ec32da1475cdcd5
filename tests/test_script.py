"""The Python API from a plain script without a main guard: the parallel feature path must not re-run the script."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap

import pytest

SCRIPT = textwrap.dedent('''
    import anseg
    from anseg import datasets, features
    from anseg.pipeline import SegmentConfig, Segmenter, segment
    from anseg.train import TrainConfig, evaluate, fit

    print("script body ran")
    train = datasets.load("synthetic", "figure", "train", n_shapes=20, progress=False)
    test = datasets.load("synthetic", "figure", "test", n_shapes=20, progress=False)
    assert sum(m.mesh.n_faces for m in train) > features.POOL_MIN_FACES  # so the feature pool really starts
    model = fit(train, train[0].label_names, SegmentConfig(cycles=1, clusters=4), TrainConfig(epochs=1, width=16, depth=1),
                progress=False)
    print("scores", evaluate(model, test, progress=False)["smoothed"]["unit_area"])
    model.save("model.pt")
    anseg.save_mesh("mesh.off", test[0].mesh)
    result = segment(anseg.load_mesh("mesh.off"), Segmenter.load("model.pt"))
    print("labels", len(result.labels))
''')


def run_script(tmp_path, text: str) -> str:
    """Run ``text`` as a plain script (no main guard) with a cold feature cache; its standard output."""
    (tmp_path / "script.py").write_text(text)
    env = {**os.environ, "ANSEG_CACHE": str(tmp_path / "cache")}
    run = subprocess.run([sys.executable, "script.py"], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stderr[-2000:]
    assert run.stdout.count("script body ran") == 1  # a worker that re-ran the script would print it again
    return run.stdout


@pytest.mark.slow
def test_a_plain_script_without_main_guard_runs_with_a_cold_cache(tmp_path):
    stdout = run_script(tmp_path, SCRIPT)
    assert "labels" in stdout
    assert len(list((tmp_path / "cache" / "features").glob("*.npy"))) >= 20


PLAN_SCRIPT = textwrap.dedent('''
    from anseg.study.runner import run_plan
    from anseg.study.store import Experiment, ResultStore
    from anseg.pipeline import SegmentConfig
    from anseg.train import TrainConfig

    print("script body ran")
    plan = [(Experiment("synthetic", "figure", 0, SegmentConfig(cycles=1, clusters=4),
                        TrainConfig(epochs=1, width=16, depth=1, seed=seed, device="cpu")), {"n_shapes": 4})
            for seed in range(2)]
    assert run_plan(plan, ResultStore("store"), workers=2) == 0
    print("stored", sum(ResultStore("store").get(e.key(x)) is not None for e, x in plan))
''')


@pytest.mark.slow
def test_a_plan_on_a_local_cluster_from_a_plain_script(tmp_path):
    assert "stored 2" in run_script(tmp_path, PLAN_SCRIPT)
