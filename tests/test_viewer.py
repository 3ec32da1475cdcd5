"""The standalone HTML view: self-contained, with its legend, and drawn in the label colours by a real browser."""

from __future__ import annotations

import os
import re
import subprocess
import sys

import numpy as np
import pytest
import torch
from conftest import (
    headless_chromium,
    needs_chromium,
    off_machine,
    offline_python,
    page_requests,
    screenshot_folder,
)

from anseg import datasets, viewer
from anseg.pipeline import SegmentConfig, segment
from anseg.train import TrainConfig, fit
from anseg.viz import palette


@pytest.fixture(scope="module")
def page(tmp_path_factory):
    torch.set_num_threads(1)
    shapes = datasets.load("synthetic", category="figure", split="all", n_shapes=5, progress=False)
    model = fit(shapes[:3], shapes[0].label_names, SegmentConfig(cycles=2, clusters=4), TrainConfig(epochs=3, width=16),
                progress=False)
    result = segment(shapes[4].mesh, model)
    folder = tmp_path_factory.mktemp("view")
    path = folder / "view.html"
    names = [*model.label_names[:-1], "<b>&odd</b>"]  # a label name is text, never markup
    viewer.write_html(result, names, path, title="figure")
    model.save(folder / "figure.pt")
    return path, result, names


@pytest.fixture(scope="module")
def scan_page(page):
    """The page `anseg segment --repair --html` writes for a scan given as STL: holes and one stray far vertex."""
    import trimesh

    from anseg.cli import main

    path, result, names = page
    mesh = result.levels[0].mesh
    holed = np.delete(mesh.faces, [0, mesh.n_faces // 2], axis=0)
    scan = path.parent / "scan.stl"
    trimesh.Trimesh(np.vstack([mesh.vertices, [[1e9, -1e9, 1e9]]]), holed, process=False).export(scan, file_type="stl")
    out = path.parent / "scan.html"
    assert main(["segment", "--model", str(path.parent / "figure.pt"), str(scan), "--repair", "--html", str(out),
                 "-o", str(path.parent / "scan.ply")]) == 0
    labels = np.loadtxt(path.parent / "scan.txt", dtype=int)
    assert labels.shape == (len(holed),)  # one label per face of the input file
    return out, labels, names  # the page names the model's labels; the colours depend on their number alone


# where a page names what a browser loads: an element's src or href, a link made by script, a CSS url(), a fetch,
# an import; the quote may be a template literal's backtick
LOADS = re.compile(r"""(?:\b(?:src|href|data|action)\s*=\s*|setAttribute\(\s*["'](?:src|href)["']\s*,\s*|"""
                   r"""\burl\(\s*|\b(?:fetch|import|importScripts)\s*\(\s*|@import\s+)["'`]?\s*(?:https?:)?//""", re.I)


def test_the_page_is_self_contained_with_a_legend(page):
    path, result, names = page
    text = path.read_text()
    assert not [text[m.start():m.end() + 60] for m in LOADS.finditer(text)]  # nothing fetched from a network
    assert "default-src 'none'" in text  # and the browser is told to fetch nothing that is not in the page
    assert "&lt;b&gt;&amp;odd&lt;/b&gt;" in text and "<b>&odd</b>" not in text
    assert text.count("coarser levels") == 1
    n_panels = len(viewer.panels(result, len(names)))
    assert n_panels == 2 * len(result.levels) + 1  # labels and attention per level, and the confidence


def _screenshot(path, name: str, folder):
    """Headless Chromium's picture of a page opened with no network, kept in ``$ANSEG_SCREENSHOTS`` when that is set.

    Fails when the page asked for anything off this machine (a favicon included).
    """
    from PIL import Image

    out = screenshot_folder(folder)
    net_log = folder / f"{name}.netlog.json"
    subprocess.run(headless_chromium(f"--log-net-log={net_log}", "--virtual-time-budget=8000", "--window-size=1200,800",
                                     f"--screenshot={out / name}", path.as_uri()), capture_output=True, timeout=120, check=True)
    assert not off_machine(page_requests(net_log, "file://")), "the page asked for something off this machine"
    return np.asarray(Image.open(out / name).convert("RGB")).astype(int)


def _assert_drawn_in(picture: np.ndarray, labels: np.ndarray, n_names: int):
    assert (picture.reshape(-1, 3).std(axis=0) > 10).all(), "a blank page"
    used = palette(n_names)[np.unique(labels)]
    # lighting shades a face's colour, so look for pixels near the hue of a predicted label, in the 3D view's area
    lower_half = picture[250:].reshape(-1, 3)
    hits = [int((np.abs(lower_half - colour).sum(axis=1) < 60).sum()) for colour in used]
    assert max(hits) > 200, f"no label colour drawn: {hits}"


@needs_chromium
def test_a_browser_draws_the_mesh_in_the_label_colours(page, tmp_path):
    path, result, names = page
    _assert_drawn_in(_screenshot(path, "viewer.png", tmp_path), result.labels, len(names))


@needs_chromium
def test_a_browser_draws_a_repaired_stl_scan_from_the_command_line(scan_page, tmp_path):
    path, labels, names = scan_page
    assert "anseg-legend" in path.read_text()
    _assert_drawn_in(_screenshot(path, "viewer_scan_stl.png", tmp_path), labels, len(names))


def test_the_command_line_writes_a_page_without_reaching_off_the_machine(page, tmp_path):
    """`anseg segment --html` in a child process whose every outside lookup or connection fails and is logged."""
    from anseg.mesh_files import save_mesh

    path, result, _ = page
    save_mesh(tmp_path / "mesh.off", result.levels[0].mesh)
    env, attempts = offline_python(tmp_path)
    args = ["segment", "--model", str(path.parent / "figure.pt"), str(tmp_path / "mesh.off"), "--html",
            str(tmp_path / "view.html"), "-o", str(tmp_path / "mesh.ply")]
    run = subprocess.run([sys.executable, "-c", f"from anseg.cli import main; raise SystemExit(main({args!r}))"],
                         env={**os.environ, **env, "OMP_NUM_THREADS": "1"}, capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
    assert not attempts.exists(), f"tried to reach {attempts.read_text().split()}"
    assert "Traceback" not in run.stderr and "Task exception" not in run.stderr, run.stderr
    assert (tmp_path / "view.html").is_file()


def test_the_live_view_follows_its_slider_and_colouring(page):
    _, result, names = page
    box = viewer.explore(result, names, jupyter_backend="static")
    (slider, choice), plotter = box.children[0].children, box.plotter
    shown = lambda: plotter.actors["mesh"].mapper.dataset
    assert shown().n_cells == result.levels[0].mesh.n_faces
    slider.value = len(result.levels) - 1
    assert shown().n_cells == result.levels[-1].mesh.n_faces
    choice.value = "confidence"  # the input level's only
    assert slider.value == 0 and shown().n_cells == result.levels[0].mesh.n_faces
    confidence = shown().cell_data["colours"].copy()
    choice.value = "labels"
    assert not np.array_equal(shown().cell_data["colours"], confidence)
    plotter.close()


def _synthetic(subdivisions: int = 3, n_levels: int = 2, attention=True, probabilities=True, stray=False):
    """A Segmentation built by hand, no model: an icosphere labelled by the sign of x, with uniform collapses.

    ``attention``: True for every level, or the levels that get one; ``stray``: a far vertex that no face uses.
    """
    import trimesh

    from anseg import collapse
    from anseg.hierarchy import Hierarchy, Level
    from anseg.mesh import Mesh
    from anseg.pipeline import Segmentation

    sphere = trimesh.creation.icosphere(subdivisions)
    vertices = np.vstack([sphere.vertices, [[1e6, -1e6, 1e6]]]) if stray else sphere.vertices
    mesh = Mesh(vertices, sphere.faces)
    rng = np.random.default_rng(0)
    levels, current = [], mesh
    for index in range(n_levels):
        has_attention = attention is True or index in attention
        levels.append(Level(current, {}, None, attention=rng.uniform(0.1, 1.0, current.n_faces) if has_attention else None))
        if index < n_levels - 1:
            current, levels[-1].record = collapse.downsample(current, None, ratio=0.5, mode="uniform")
    labels = (mesh.face_centroids[:, 0] > 0).astype(np.int64)
    probs = np.column_stack([1 - labels, labels]) * 0.6 + 0.2 if probabilities else None
    return Segmentation(labels=labels, probabilities=probs, unsmoothed_labels=labels, levels=Hierarchy(levels))


def _legend_notes(path) -> list[str]:
    import html
    import json

    legend = json.loads(re.search(r"box\.innerHTML = (\".*?\"); document", path.read_text()).group(1).replace("<\\/", "</"))
    return [html.unescape(note) for note in re.findall(r'<p class="anseg-note"[^>]*>(.*?)</p>', legend)]


def _payload(path) -> int:
    """Characters of the scene vtk.js draws (base64 of its zipped arrays): the part of the page that grows with faces."""
    return len(re.search(r'const base64Str = "([^"]*)"', path.read_text()).group(1))


def test_a_large_mesh_is_drawn_decimated_and_the_legend_says_so(tmp_path, monkeypatch):
    result = _synthetic(subdivisions=4)  # 5120 faces; the panels hold 3 x 5120 + 2 x 2560
    full = viewer.write_html(result, ["a", "b"], tmp_path / "full.html")
    assert _legend_notes(full) == []
    monkeypatch.setattr(viewer, "DISPLAY_MAX_FACES", 2000)
    light = viewer.write_html(result, ["a", "b"], tmp_path / "light.html")
    [note] = _legend_notes(light)
    drawn, held = (int(n.replace(",", "")) for n in re.search(r"decimated to ([\d,]+) faces, of the ([\d,]+)", note).groups())
    assert drawn <= 2000 and held == 3 * 5120 + 2 * 2560
    assert "5,120 with 400" in note  # the input mesh, as drawn on each of its three panels
    assert _payload(light) < _payload(full) / 4  # a tenth of the faces drawn, and what every scene holds
    assert len(result.labels) == result.levels[0].mesh.n_faces  # the data keep one label per input face

    # each drawn face has the colour of the input faces it covers: the label of its side of x = 0
    shown, _ = viewer._for_display(viewer.panels(result, 2), 2000)
    row, column, mesh, rgb = shown[0]
    assert (row, column, mesh.n_faces) == (0, 0, 400)
    expected = palette(2)[(mesh.face_centroids[:, 0] > 0).astype(int)]
    assert (rgb == expected).all(axis=1).mean() > 0.95


def test_below_the_threshold_the_page_draws_every_face():
    result = _synthetic(subdivisions=3)
    held = viewer.panels(result, 2)
    total = sum(mesh.n_faces for _, _, mesh, _ in held)
    shown, note = viewer._for_display(held, total)
    assert note is None
    assert [(r, c, m, rgb) for r, c, m, rgb in shown] == [(r, c, m, rgb) for r, c, m, rgb in held]  # the same objects
    # above it, the smaller panels stay whole and the larger share the rest evenly
    assert viewer._face_cap([10, 100, 100], 110) == 50 and viewer._face_cap([10, 100], 110) is None


def test_a_panel_left_out_is_named_in_the_legend(tmp_path):
    """A uniform hierarchy segmented with combine="coarsest" holds attention on its last level only."""
    result = _synthetic(n_levels=3, attention=[2], probabilities=False)
    assert len(viewer.panels(result, 2)) == 3 + 1  # the labels of each level, the last level's attention
    notes = _legend_notes(viewer.write_html(result, ["a", "b"], tmp_path / "view.html"))
    assert notes == ["No attention panel for levels 0, 1: the segmentation holds no attention there "
                     "(anseg.pipeline.fill_attention computes it).",
                     "No confidence panel: the segmentation holds no class probabilities."]
    assert viewer.missing_panels(_synthetic()) == []


def test_a_vertex_no_face_uses_does_not_shrink_the_panels():
    """The page scales each panel to its mesh's bounding box: a stray far vertex would make the shape a dot."""
    result = _synthetic(stray=True)
    shown, _ = viewer._for_display(viewer.panels(result, 2), viewer.DISPLAY_MAX_FACES)
    for _, _, mesh, rgb in shown:
        assert np.abs(mesh.vertices).max() < 1.01 and len(rgb) == mesh.n_faces
