"""The `anseg` command with a user's own mesh: outputs written as one, failing fast, and clear words for bad files."""

from __future__ import annotations

import subprocess
import sys
from types import SimpleNamespace

import numpy as np
import pytest
from conftest import grid_mesh

from anseg import cli
from anseg.cli import main
from anseg.mesh import Mesh
from anseg.mesh_files import save_mesh

FAR = 1e9


def run_cli(*args):
    return subprocess.run([sys.executable, "-m", "anseg.cli", *map(str, args)], capture_output=True, text=True)


def blocked(tmp_path, name):
    """A target that cannot be written whoever we are (tests may run as root): its folder is a regular file."""
    (tmp_path / "file").write_text("in the way\n")
    return tmp_path / "file" / name


# every output flag of every command; the others' outputs exist before the run and must be left byte for byte
OUTPUT_FLAGS = {
    "segment -o": (["segment", "--model", "psb/Teddy", "{mesh}", "-o", "{ply}", "--labels", "{txt}", "--html", "{html}"], "ply"),
    "segment --labels": (["segment", "--model", "psb/Teddy", "{mesh}", "-o", "{ply}", "--labels", "{txt}", "--html", "{html}"],
                         "txt"),
    "segment --html": (["segment", "--model", "psb/Teddy", "{mesh}", "-o", "{ply}", "--labels", "{txt}", "--html", "{html}"],
                       "html"),
    "features -o": (["features", "{mesh}", "-o", "{npy}", "--groups", "edge"], "npy"),
    "evaluate --json": (["evaluate", "psb/Teddy", "--category", "Teddy", "--json", "{json}"], "json"),
    "train -o": (["train", "--dataset", "synthetic", "--category", "vessel", "--epochs", "1", "--cycles", "1",
                  "--data", "{tmp}/no-data", "-o", "{pt}"], "pt"),
}


@pytest.mark.parametrize("flag", list(OUTPUT_FLAGS))
def test_an_unwritable_output_fails_at_once_and_touches_no_existing_file(tmp_path, flag):
    template, bad = OUTPUT_FLAGS[flag]
    mesh = tmp_path / "mesh.off"
    save_mesh(mesh, grid_mesh(6, closed=True))
    paths = {kind: tmp_path / f"out.{kind}" for kind in ("ply", "txt", "html", "npy", "json", "pt")}
    paths[bad] = blocked(tmp_path, f"out.{bad}")
    before = {}
    for kind, path in paths.items():
        if kind != bad:
            path.write_bytes(f"the {kind} of an earlier run\n".encode())
            before[path] = path.read_bytes()
    args = [a.format(mesh=mesh, tmp=tmp_path, **paths) for a in template]
    result = run_cli(*args)
    assert result.returncode == 2, result.stderr
    assert result.stderr.count("\n") == 1 and str(paths[bad]) in result.stderr, result.stderr
    assert ".tmp" not in result.stderr and "Traceback" not in result.stderr
    assert {path: path.read_bytes() for path in before} == before
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(["file", "mesh.off", *(p.name for p in before)])


def stub_model(monkeypatch, n_classes=3):
    """A model and a segment() that cost nothing: what is tested here is what the command does with their output."""
    import anseg.pipeline

    model = SimpleNamespace(config=None, n_classes=n_classes, label_names=[f"part{i}" for i in range(n_classes)],
                            network=SimpleNamespace(parameters=lambda: iter([SimpleNamespace(device="cpu")])))
    monkeypatch.setattr(cli, "_load_model", lambda path: model)
    monkeypatch.setattr(anseg.pipeline, "segment",
                        lambda mesh, *a, **k: SimpleNamespace(labels=np.arange(mesh.n_faces) % 3, levels=None))
    monkeypatch.setattr(anseg.pipeline, "fill_attention", lambda model, levels, device="cpu": levels)
    return model


def test_a_failure_while_writing_leaves_every_existing_output_as_it_was(tmp_path, monkeypatch, capsys):
    import anseg.viewer

    stub_model(monkeypatch)
    mesh = tmp_path / "mesh.off"
    save_mesh(mesh, grid_mesh(4, closed=True))
    outputs = [tmp_path / "out.ply", tmp_path / "out.txt", tmp_path / "page.html"]
    for path in outputs:
        path.write_text("an earlier run\n")

    def disk_full(result, names, path, title=""):
        open(path, "w").write("<html>half a page")
        raise OSError(28, "No space left on device", str(path))  # the writer names the file it was given

    monkeypatch.setattr(anseg.viewer, "write_html", disk_full)
    argv = ["segment", "--model", "psb/Teddy", str(mesh), "-o", str(outputs[0]), "--html", str(outputs[2])]
    assert main(argv) == 2
    error = capsys.readouterr().err
    assert error == f"anseg segment: error: {outputs[2]}: No space left on device\n"
    assert all(path.read_text() == "an earlier run\n" for path in outputs)
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(["mesh.off", *(p.name for p in outputs)])
    # and when every writer succeeds, every output is replaced
    monkeypatch.setattr(anseg.viewer, "write_html", lambda result, names, path, title="": open(path, "w").write("<html>"))
    assert main(argv) == 0
    assert outputs[2].read_text() == "<html>" and len(np.loadtxt(outputs[1])) == grid_mesh(4, closed=True).n_faces


def sphere_and_a_far_facet() -> tuple[Mesh, Mesh]:
    """A clean closed mesh, and the same with one more triangle a billion units away (as in a user's STL)."""
    sphere = grid_mesh(5, closed=True)
    far = np.array([[FAR, FAR, FAR], [FAR + 1, FAR, FAR], [FAR, FAR + 1, FAR]])
    n = sphere.n_vertices
    return sphere, Mesh(np.vstack([sphere.vertices, far]), np.vstack([sphere.faces, [[n, n + 1, n + 2]]]))


def test_one_far_facet_does_not_spoil_a_scan_on_the_command_line(tmp_path, monkeypatch, capsys):
    import trimesh

    sphere, with_far = sphere_and_a_far_facet()
    # STL keeps float32: there the far facet's corners round to one point, a degenerate face; --repair drops it alone
    stl = tmp_path / "scan.stl"
    trimesh.Trimesh(with_far.vertices, with_far.faces, process=False).export(stl)
    refused = run_cli("features", stl, "-o", tmp_path / "x.npy", "--groups", "edge")
    assert refused.returncode == 2 and "1 face of zero area" in refused.stderr
    assert "--repair" in refused.stderr and "anseg.repair" not in refused.stderr
    result = run_cli("features", stl, "-o", tmp_path / "x.npy", "--groups", "edge", "--repair")
    assert result.returncode == 0, result.stderr
    assert np.load(tmp_path / "x.npy").shape[0] == sphere.n_faces
    stub_model(monkeypatch)
    assert main(["segment", "--model", "psb/Teddy", str(stl), "--repair", "-o", str(tmp_path / "scan.ply")]) == 0, \
        capsys.readouterr().err
    assert np.loadtxt(tmp_path / "scan.txt").shape == (with_far.n_faces,)  # a label for every input face
    # in float64 (OFF) the far facet is a good triangle: the mesh loads as it is
    off = tmp_path / "scan.off"
    save_mesh(off, with_far)
    assert main(["features", str(off), "-o", str(tmp_path / "y.npy"), "--groups", "edge"]) == 0
    assert np.load(tmp_path / "y.npy").shape[0] == with_far.n_faces


def test_evaluate_takes_the_names_segment_takes(tmp_path):
    result = run_cli("evaluate", "psb/Teddy", "--category", "Teddy", "--data", tmp_path / "no-data")
    assert result.returncode == 2 and result.stderr.count("\n") == 1
    assert "no such model file" not in result.stderr and "no-data" in result.stderr, result.stderr
    result = run_cli("evaluate", "psb/Nope")
    assert result.returncode == 2 and "no such model file, nor a pretrained model" in result.stderr


@pytest.mark.parametrize("argv", [["segment", "--model", "psb/Teddy", "{dir}"], ["features", "{dir}", "-o", "{dir}/x.npy"],
                                  ["segment", "{dir}", "{dir}/m.off"], ["evaluate", "{dir}"]])
def test_a_directory_is_named_as_one(tmp_path, argv):
    result = run_cli(*[a.format(dir=tmp_path) for a in argv])
    assert result.returncode == 2 and result.stderr.count("\n") == 1
    assert f"{tmp_path}: is a directory" in result.stderr, result.stderr


@pytest.mark.parametrize("suffix", [".off", ".obj", ".ply", ".stl", ".glb", ".gltf"])
@pytest.mark.parametrize("cut", ["empty", "truncated"])
def test_an_empty_or_truncated_file_is_one_line_about_the_file(tmp_path, suffix, cut):
    import trimesh

    path = tmp_path / f"mesh{suffix}"
    trimesh.Trimesh(*(lambda m: (m.vertices, m.faces))(grid_mesh(4, closed=True)), process=False).export(path)
    data = path.read_bytes()
    path.write_bytes(b"" if cut == "empty" else data[: len(data) * 2 // 3])
    result = run_cli("features", path, "-o", tmp_path / "x.npy")
    assert result.returncode == 2 and result.stderr.count("\n") == 1, result.stderr
    assert str(path) in result.stderr and "Error" not in result.stderr, result.stderr


def test_a_failing_command_answers_before_importing_torch(tmp_path):
    """Importing torch takes seconds: bad input is answered without it."""
    probe = ("import sys; from anseg.cli import main; "
             "codes = [main(a) for a in sys.argv[1:] and [['segment', '--model', 'psb/Teddy', sys.argv[1]], "
             "['segment', 'psb/Teddy', sys.argv[1]], ['features', sys.argv[1], '-o', 'x.npy'], ['evaluate', 'psb/Nope'], "
             "['train', '-o', sys.argv[2]], ['segment', '--model', 'psb/Teddy', sys.argv[3], '-o', sys.argv[2]]]]; "
             "print(codes, 'torch' in sys.modules)")
    mesh = tmp_path / "mesh.off"
    save_mesh(mesh, grid_mesh(4, closed=True))
    result = subprocess.run([sys.executable, "-c", probe, str(tmp_path / "absent.off"), str(blocked(tmp_path, "x")), str(mesh)],
                            capture_output=True, text=True)
    assert result.stdout.split() == ["[2,", "2,", "2,", "2,", "2,", "2]", "False"], result.stdout + result.stderr


def test_models_shows_revision_date_and_with_v_the_label_names(monkeypatch, capsys):
    from anseg import pretrained

    monkeypatch.setattr(pretrained, "names", lambda: ["psb/Teddy"])
    card = pretrained.card("psb/Teddy")
    assert main(["models"]) == 0
    line = capsys.readouterr().out
    assert f"revision {card['code_revision'][:8]}" in line and card["date"][:10] in line
    assert main(["models", "-v"]) == 0
    labels = cli._load_model(pretrained.path("psb/Teddy")).label_names
    assert f"labels: {', '.join(labels)}" in capsys.readouterr().out
