"""The `anseg` command: help, clear errors for bad input, and a tiny train -> segment -> evaluate run."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
from conftest import grid_mesh

from anseg.cli import main
from anseg.mesh_files import save_mesh


def run_cli(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "anseg.cli", *map(str, args)], capture_output=True, text=True, cwd=cwd)


@pytest.mark.parametrize("command", [[], ["train"], ["segment"], ["evaluate"], ["features"]])
def test_help_everywhere(command, capsys):
    with pytest.raises(SystemExit) as exit_info:
        main([*command, "--help"])
    assert exit_info.value.code == 0
    assert "usage: anseg" in capsys.readouterr().out


ALL_FORMATS = (".off", ".obj", ".ply", ".stl", ".glb", ".gltf")


@pytest.mark.parametrize("command", ["segment", "features"])
def test_help_names_every_mesh_format(command, capsys):
    with pytest.raises(SystemExit):
        main([command, "--help"])
    help_text = " ".join(capsys.readouterr().out.split())  # argparse wraps long lines
    assert all(suffix in help_text for suffix in ALL_FORMATS)


def test_an_unsupported_format_is_one_line_naming_every_format(tmp_path):
    path = tmp_path / "mesh.3ds"
    path.write_text("not read\n")
    result = run_cli("features", path, "-o", tmp_path / "x.npy")
    assert result.returncode == 2 and result.stderr.count("\n") == 1
    assert all(suffix in result.stderr for suffix in ALL_FORMATS)


def test_features_of_an_stl_file(tmp_path):
    import trimesh

    sphere = grid_mesh(4, closed=True)
    path = tmp_path / "sphere.stl"
    trimesh.Trimesh(sphere.vertices, sphere.faces, process=False).export(path)
    out = tmp_path / "f.npy"
    assert main(["features", str(path), "-o", str(out), "--groups", "edge"]) == 0
    assert np.load(out).shape[0] == sphere.n_faces


def test_features_writes_npy(tmp_path, capsys):
    mesh_path = tmp_path / "sphere.ply"
    sphere = grid_mesh(4, closed=True)
    save_mesh(mesh_path, sphere)
    out = tmp_path / "f.npy"
    assert main(["features", str(mesh_path), "-o", str(out), "--groups", "edge,angles,gc"]) == 0
    x = np.load(out)
    assert x.shape[0] == sphere.n_faces and np.isfinite(x).all()


@pytest.mark.parametrize(
    "content, message",
    [(None, "no such file"), ("OFF\n3 1 0\n0 0 0\n1 0 0\n2 0 0\n3 0 1 2\n", "of zero area"), ("garbage\n", "cannot read mesh")],
)
def test_bad_mesh_gives_message_not_traceback(tmp_path, content, message):
    path = tmp_path / "bad.off"
    if content is not None:
        path.write_text(content)
    result = run_cli("features", path, "-o", tmp_path / "x.npy")
    assert result.returncode == 2
    assert message in result.stderr and "Traceback" not in result.stderr


def test_damaged_model_file_is_one_line_of_our_own(tmp_path):
    mesh_path = tmp_path / "sphere.ply"
    save_mesh(mesh_path, grid_mesh(4, closed=True))
    (tmp_path / "bad.pt").write_bytes(b"garbage")
    result = run_cli("segment", tmp_path / "bad.pt", mesh_path)
    assert result.returncode == 2 and result.stderr.count("\n") == 1
    assert "not a model written by anseg" in result.stderr and "weights_only" not in result.stderr


def test_features_repair_handles_repeated_faces(tmp_path):
    sphere = grid_mesh(4, closed=True)
    path = tmp_path / "twice.off"
    save_mesh(path, type(sphere)(sphere.vertices, np.vstack([sphere.faces, sphere.faces[:3]])))
    refused = run_cli("features", path, "-o", tmp_path / "x.npy")
    assert refused.returncode == 2 and "3 faces repeat" in refused.stderr and "--repair" in refused.stderr
    result = run_cli("features", path, "-o", tmp_path / "x.npy", "--groups", "edge", "--repair")
    assert result.returncode == 0, result.stderr
    assert np.load(tmp_path / "x.npy").shape[0] == sphere.n_faces


def test_unknown_dataset_and_missing_model(tmp_path):
    result = run_cli("evaluate", tmp_path / "missing.pt", "--dataset", "psb")
    assert result.returncode == 2 and "no such model file" in result.stderr and "Traceback" not in result.stderr
    result = run_cli("train", "--dataset", "nonsense", "-o", tmp_path / "m.pt")
    assert result.returncode == 2 and "nonsense" in result.stderr and "Traceback" not in result.stderr


@pytest.mark.slow
def test_train_segment_evaluate(tmp_path, monkeypatch):
    model = tmp_path / "vessel.pt"
    result = run_cli("train", "--dataset", "synthetic", "--category", "vessel",
                     "--epochs", "1", "--cycles", "1", "-o", model, cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert model.is_file() and not model.with_suffix(".ckpt").exists()
    from anseg import datasets

    shape = datasets.load("synthetic", category="vessel", split="test", progress=False)[0]
    mesh_path = tmp_path / "vessel.off"
    save_mesh(mesh_path, shape.mesh)
    result = run_cli("segment", model, mesh_path, "-o", tmp_path / "out.ply")
    assert result.returncode == 0, result.stderr
    labels = np.loadtxt(tmp_path / "out.txt", dtype=int)
    assert labels.shape == (shape.mesh.n_faces,) and labels.min() >= 0
    assert (tmp_path / "out.ply").is_file()
    result = run_cli("evaluate", model, "--dataset", "synthetic", "--category", "vessel", "--json", tmp_path / "scores.json")
    assert result.returncode == 0, result.stderr
    assert "unit_area" in result.stdout and (tmp_path / "scores.json").is_file()
    # a non-manifold mesh (a fin glued along an edge and a repeated face): refused, then segmented with --repair,
    # one label for every input face
    mesh = shape.mesh
    u, w = mesh.edges[0]
    fin = np.vstack([mesh.vertices, (mesh.vertices[u] + mesh.vertices[w]) / 2 + 0.1 * mesh.face_normals[0]])
    glued = type(mesh)(fin, np.vstack([mesh.faces, [[u, w, mesh.n_vertices]], mesh.faces[:1]]))
    save_mesh(tmp_path / "fin.off", glued)
    refused = run_cli("segment", model, tmp_path / "fin.off")
    assert refused.returncode == 2 and "--repair" in refused.stderr
    result = run_cli("segment", model, tmp_path / "fin.off", "--repair", "-o", tmp_path / "fin.ply")
    assert result.returncode == 0, result.stderr
    labels = np.loadtxt(tmp_path / "fin.txt", dtype=int)
    assert labels.shape == (glued.n_faces,) and labels.min() >= 0
    from test_mesh import (  # an edge of 4 faces; cones at their apex
        grid_with_a_fin,
        two_cones_touching_at_their_apex,
    )

    for name, broken in (("fins", grid_with_a_fin(2)), ("cones", two_cones_touching_at_their_apex())):
        save_mesh(tmp_path / f"{name}.off", broken)
        result = run_cli("segment", model, tmp_path / f"{name}.off", "--repair", "-o", tmp_path / f"{name}.ply")
        assert result.returncode == 0, result.stderr
        assert np.loadtxt(tmp_path / f"{name}.txt", dtype=int).shape == (broken.n_faces,)
    # a mesh too small for the model's cycles: segmented, with a one-line warning that says so
    triangle = tmp_path / "triangle.off"
    triangle.write_text("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n")
    result = run_cli("segment", model, triangle, "-o", tmp_path / "tri.ply")
    assert result.returncode == 0, result.stderr
    assert "warning: 1 faces are too few for 1 cycles" in result.stderr and result.stderr.count("\n") == 1
    result = run_cli("segment", model, triangle, "--smooth-weight", "-3")
    assert result.returncode == 2 and "--smooth-weight: must be a number >= 0" in result.stderr
    # interrupted while writing the label file: no partial file under the final name, no temporary left
    def interrupted(path, *args, **kwargs):
        open(path, "w").write("0\n")
        raise KeyboardInterrupt

    monkeypatch.setattr(np, "savetxt", interrupted)
    assert main(["segment", str(model), str(mesh_path), "-o", str(tmp_path / "cut.ply")]) == 130
    assert not (tmp_path / "cut.txt").exists() and not list(tmp_path.glob(".cut*"))


@pytest.mark.slow
def test_a_users_scan_and_cad_part_segment_with_a_view(tmp_path):
    """Meshes from no benchmark: a scan with holes as binary STL, a CAD part as GLB with a stray far vertex.

    Each goes through ``segment --model FILE --repair --html``: one label per input face, the same labels as
    the same faces given as OFF (the format and the stray vertex change nothing), and a page with its legend.
    """
    import torch
    import trimesh

    from anseg import datasets
    from anseg.mesh import Mesh
    from anseg.pipeline import SegmentConfig
    from anseg.train import TrainConfig, fit

    torch.set_num_threads(1)
    shapes = datasets.load("synthetic", category="vessel", split="all", n_shapes=5, progress=False)
    model = tmp_path / "vessel.pt"
    fit(shapes[:3], shapes[0].label_names, SegmentConfig(cycles=1, clusters=4), TrainConfig(epochs=1, width=16),
        progress=False).save(model)
    mesh = shapes[4].mesh
    holed = Mesh(mesh.vertices, np.delete(mesh.faces, [0, mesh.n_faces // 2, mesh.n_faces - 1], axis=0))
    trimesh.Trimesh(holed.vertices, holed.faces, process=False).export(tmp_path / "scan.stl", file_type="stl")
    trimesh.Trimesh(np.vstack([mesh.vertices, [[1e9, 1e9, 1e9]]]), mesh.faces, process=False).export(tmp_path / "part.glb")
    for name, same_faces in (("scan.stl", holed), ("part.glb", mesh)):
        stem = name.split(".")[0]
        save_mesh(tmp_path / f"{stem}.off", same_faces)
        for source in (name, f"{stem}.off"):
            result = run_cli("segment", "--model", model, tmp_path / source, "--repair", "--html",
                             tmp_path / f"{source}.html", "-o", tmp_path / f"{source}.ply")
            assert result.returncode == 0, result.stderr
        labels = np.loadtxt(tmp_path / f"{name}.txt", dtype=int)
        assert labels.shape == (same_faces.n_faces,)
        assert np.array_equal(labels, np.loadtxt(tmp_path / f"{stem}.off.txt", dtype=int))
        page = (tmp_path / f"{name}.html").read_text()
        assert "anseg-legend" in page and all(n in page for n in shapes[0].label_names)


def test_a_reader_that_leaves_early_ends_the_listing_quietly(monkeypatch, capsys):
    import os

    read_end, write_end = os.pipe()
    os.close(read_end)  # `anseg models | head -0`: nobody reads
    with capsys.disabled():
        monkeypatch.setattr(sys, "stdout", os.fdopen(write_end, "w", buffering=1))
        monkeypatch.setattr("anseg.pretrained.names", lambda: ["psb/Human"])
        monkeypatch.setattr("anseg.pretrained.describe", lambda name: name)
        assert main(["models"]) == 141
        sys.stdout.close()
