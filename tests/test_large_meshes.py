"""Meshes above the network's face limit: segmented on their collapse, labels carried back to every face, progress shown."""

from __future__ import annotations

import math
import os
import subprocess
import sys
from dataclasses import replace

import numpy as np
import pytest
import torch

from anseg import collapse, datasets
from anseg.graphcut import smooth
from anseg.pipeline import SegmentConfig, fill_attention, segment
from anseg.train import TrainConfig, fit

LIMIT = 1000  # the synthetic figures have 3,916 faces


@pytest.fixture(scope="module")
def shapes():
    return datasets.load("synthetic", category="figure", split="all", n_shapes=5, progress=False)


@pytest.fixture(scope="module")
def model(shapes):
    torch.set_num_threads(1)
    # the input's own face order (canonical off), so that level 0 is the input mesh itself; canonical below
    return fit(shapes[:3], shapes[0].label_names, SegmentConfig(cycles=2, clusters=4, canonical=False),
               TrainConfig(epochs=1, width=16), progress=False)


def test_a_mesh_above_the_limit_is_segmented_on_its_collapse_and_labelled_on_every_face(model, shapes):
    mesh = shapes[4].mesh
    result = segment(mesh, model, network_faces=LIMIT)
    first, *network_levels = result.levels
    assert first.mesh is mesh and first.layout is None and first.attention is None
    assert network_levels[0].mesh.n_faces <= LIMIT + 1 and len(network_levels) == model.config.cycles + 1
    # what the network made of the collapse, carried back through its record, then the graph cut on the mesh itself
    inner = segment(network_levels[0].mesh, model, replace(model.config, smooth_weight=0.0), network_faces=math.inf)
    probs = collapse.upsample(first.record, inner.probabilities)
    np.testing.assert_array_equal(result.probabilities, probs)
    np.testing.assert_array_equal(result.unsmoothed_labels, probs.argmax(axis=1))
    np.testing.assert_array_equal(result.labels, smooth(mesh, probs, model.config.smooth_weight,
                                                        model.config.concave_discount))
    # every level reads the input's labels, as the viewer asks; every level but the input gets its attention
    assert all(len(result.levels.labels_on(i, result.labels, model.n_classes)) == level.mesh.n_faces
               for i, level in enumerate(result.levels))
    fill_attention(model, result.levels)
    assert first.attention is None and all(level.attention is not None for level in network_levels)


def test_a_canonical_model_labels_every_face_above_the_limit_whatever_the_pose(model, shapes):
    from scipy.spatial.transform import Rotation

    from anseg.mesh import Mesh

    config = replace(model.config, canonical=True, layout_frame="principal")
    mesh = shapes[4].mesh
    result = segment(mesh, model, config, network_faces=LIMIT)
    assert result.labels.shape == (mesh.n_faces,) and result.levels[1].mesh.n_faces <= LIMIT + 1
    turned = Mesh(Rotation.random(random_state=2).apply(mesh.vertices) * 3.0 - 1.0, mesh.faces[::-1])
    np.testing.assert_array_equal(segment(turned, model, config, network_faces=LIMIT).labels[::-1], result.labels)


def test_a_mesh_at_the_limit_is_segmented_whole(model, shapes):
    mesh = shapes[4].mesh
    whole = segment(mesh, model, network_faces=mesh.n_faces)
    assert whole.levels[0].layout is not None and whole.levels[0].mesh.n_faces == mesh.n_faces
    np.testing.assert_array_equal(whole.probabilities, segment(mesh, model, network_faces=math.inf).probabilities)


def segment_files(tmp_path, model, mesh) -> list[str]:
    """`anseg segment`'s arguments for ``model`` and ``mesh``, written to ``tmp_path``."""
    from anseg.mesh_files import save_mesh

    model.save(tmp_path / "model.pt")
    save_mesh(tmp_path / "mesh.off", mesh)
    return ["segment", str(tmp_path / "model.pt"), str(tmp_path / "mesh.off"), "-o", str(tmp_path / "out.ply")]


def test_progress_shows_on_a_pipe_when_asked(tmp_path, model, shapes):
    """In a fresh process without ``TQDM_DISABLE`` (tqdm reads it on import), the limit lowered to LIMIT faces."""
    mesh = shapes[4].mesh
    code = ("import sys, anseg.pipeline as pipeline; from anseg.cli import main; "
            f"pipeline.NETWORK_FACES = {LIMIT}; sys.exit(main(sys.argv[1:]))")
    env = {k: v for k, v in os.environ.items() if k != "TQDM_DISABLE"}
    run = subprocess.run([sys.executable, "-c", code, *segment_files(tmp_path, model, mesh), "--progress"],
                         capture_output=True, text=True, env=env)
    assert run.returncode == 0 and f"segment {mesh.n_faces} faces" in run.stderr, run.stderr


@pytest.mark.parametrize("flags", [[], ["--quiet"]])
def test_no_progress_on_a_pipe_by_default_nor_when_quiet(tmp_path, model, shapes, monkeypatch, capsys, flags):
    import anseg.pipeline as pipeline
    from anseg.cli import main

    monkeypatch.setattr(pipeline, "NETWORK_FACES", LIMIT)
    assert main([*segment_files(tmp_path, model, shapes[4].mesh), *flags]) == 0
    assert capsys.readouterr().err == ""
