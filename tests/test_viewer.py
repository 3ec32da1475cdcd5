"""The standalone HTML view: self-contained, with its legend, and in a real browser the labelled mesh large, every
other view one click away."""

from __future__ import annotations

import contextlib
import os
import re
import subprocess
import sys

import numpy as np
import pytest
import torch
from conftest import needs_chromium, off_machine, offline_python, page_requests
from viewing import Browser, keep, label_hits, made_segmentation, screenshot_when, sectors, wait, window_share

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
    assert text.count("each higher level a coarser one") == 1
    n_panels = len(viewer.panels(result, len(names)))
    assert n_panels == 2 * len(result.levels) + 1  # labels and attention per level, and the confidence
    assert text.count('data-level="') == len(result.levels) and text.count('data-kind="') == 3


@contextlib.contextmanager
def _opened(path, folder):
    """The page in headless Chromium once it shows its first view, opened with no network.

    Fails, once the browser is closed, when the page asked for anything off this machine (a favicon included).
    """
    browser = Browser(folder)
    try:
        browser.call("Page.navigate", url=path.as_uri())
        wait(lambda: _shown(browser) == "labels 0", 120, "the page's first view")
        yield browser
    finally:
        browser.close()
    assert not off_machine(page_requests(browser.net_log, "file://")), "the page asked for something off this machine"


def _shown(browser) -> str | None:
    return browser.js("document.documentElement.dataset.ansegShown")


def _click(browser, selector: str, shows: str):
    """Click the page's button ``selector`` and wait until the page says it shows ``shows`` ("colouring level")."""
    browser.js(f"document.querySelector('#anseg-legend {selector}').click(); true")
    wait(lambda: _shown(browser) == shows, 120, f"the page to show {shows}")


def _picture(browser, name: str, folder) -> np.ndarray:
    """The window once the view has drawn, kept as ``name`` in the screenshot folder."""
    view = browser.box("#anseg-view")
    picture = screenshot_when(browser, lambda shot: window_share(shot, view) > 0.01, 300, "the view to draw", folder)
    keep(name, picture, folder)
    return picture


def _assert_shows(picture, view, labels, n_names: int, share: float):
    """The mesh covers at least ``share`` of the window, is framed to its view, and shows every label of ``labels``."""
    assert window_share(picture, view) >= share, f"the mesh covers {window_share(picture, view):.1%} of the window"
    x, y, w, h = view
    drawn = (255 - picture[y:y + h, x:x + w].astype(int)).sum(axis=2) > 30
    rows, columns = np.flatnonzero(drawn.any(axis=1)), np.flatnonzero(drawn.any(axis=0))
    assert max((rows[-1] - rows[0]) / h, (columns[-1] - columns[0]) / w) > 0.85, "the mesh is not framed to its view"
    hits = label_hits(picture, view, labels, n_names)
    assert min(hits.values()) > 200, f"pixels of each label's colour: {hits}"


@needs_chromium
def test_the_page_shows_the_labelled_mesh_large_and_every_view_one_click_away(tmp_path):
    """A flattened sphere in five sectors, seen from above: the page opens on its labels, turns, and switches."""
    result = made_segmentation(subdivisions=4, n_levels=3, n_labels=5, flatten=0.6)
    names = ["one", "two", "three", "four", "five"]
    path = viewer.write_html(result, names, tmp_path / "view.html")
    with _opened(path, tmp_path) as browser:
        view = browser.box("#anseg-view")
        first = _picture(browser, "viewer_labels.png", tmp_path)
        _assert_shows(first, view, result.labels, len(names), 0.25)
        x, y, w, h = view
        drag = [("mousePressed", 0), *(("mouseMoved", step) for step in range(1, 11)), ("mouseReleased", 10)]
        for kind, step in drag:  # a drag to the right and down, in ten moves
            browser.call("Input.dispatchMouseEvent", type=kind, x=x + w // 2 + 15 * step, y=y + h // 2 + 6 * step,
                         button="left", buttons=int(kind != "mouseReleased"), clickCount=1)
        turned = _picture(browser, "viewer_turned.png", tmp_path)
        assert (np.abs(turned.astype(int) - first).max(axis=2) > 30).mean() > 0.05, "a drag did not turn the mesh"
        _click(browser, "[data-front]", "labels 0")
        assert (np.abs(_picture(browser, "viewer_front.png", tmp_path).astype(int) - first).max(axis=2) > 30).mean() < 0.01

        views = {}
        for selector, shows in [('[data-kind="attention"]', "attention 0"), ('[data-level="2"]', "attention 2"),
                                ('[data-kind="confidence"]', "confidence 0"), ('[data-level="1"]', "labels 1")]:
            _click(browser, selector, shows)
            views[shows] = _picture(browser, f"viewer_{shows.replace(' ', '_')}.png", tmp_path)
            assert window_share(views[shows], view) >= 0.25, f"{shows}: the mesh covers too little of the window"
        # the attention and the confidence leave the label colours; the labels of a coarser level keep them
        before = sum(label_hits(first, view, result.labels, len(names)).values())
        for shows in ("attention 0", "attention 2", "confidence 0"):
            assert sum(label_hits(views[shows], view, result.labels, len(names)).values()) < before / 5, shows
        _assert_shows(views["labels 1"], view, result.labels, len(names), 0.25)


@needs_chromium
def test_a_browser_draws_the_figure_in_its_label_colours(page, tmp_path):
    path, result, names = page
    with _opened(path, tmp_path) as browser:
        _assert_shows(_picture(browser, "viewer.png", tmp_path), browser.box("#anseg-view"), result.labels, len(names), 0.05)


@needs_chromium
def test_a_browser_draws_a_repaired_stl_scan_from_the_command_line(scan_page, tmp_path):
    path, labels, names = scan_page
    with _opened(path, tmp_path) as browser:
        picture = _picture(browser, "viewer_scan_stl.png", tmp_path)
        _assert_shows(picture, browser.box("#anseg-view"), labels, len(names), 0.05)


@needs_chromium
def test_the_page_of_a_psb_teddy_shows_it_large_in_every_label_colour(data_root, tmp_path):
    """`anseg segment --model psb/Teddy teddy.off --html teddy.html` on PSB Teddy 161, the page opened at 1400 x 900.

    A quarter of the window is what a shape as stout as this teddy covers
    once framed; a slimmer one fills the view's height and covers less
    (``results/benchmarks/page_size_teddy.txt`` has all twenty).
    """
    from anseg.cli import main
    from anseg.mesh_files import save_mesh
    from anseg.pipeline import Segmenter

    teddy = next(m for m in datasets.load("psb", category="Teddy", split="all", root=data_root) if m.name == "Teddy/161")
    save_mesh(tmp_path / "teddy.off", teddy.mesh)
    assert main(["segment", "--model", "psb/Teddy", str(tmp_path / "teddy.off"), "--html", str(tmp_path / "teddy.html"),
                 "-o", str(tmp_path / "teddy.ply")]) == 0
    labels = np.loadtxt(tmp_path / "teddy.txt", dtype=int)
    with _opened(tmp_path / "teddy.html", tmp_path) as browser:
        picture = _picture(browser, "viewer_teddy.png", tmp_path)
        _assert_shows(picture, browser.box("#anseg-view"), labels, Segmenter.pretrained("psb/Teddy").n_classes, 0.25)


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


def test_the_live_view_follows_its_buttons_and_frames_each_mesh(page):
    _, result, names = page
    box = viewer.explore(result, names, jupyter_backend="static")
    plotter = box.plotter
    shown = lambda: plotter.actors["mesh"].mapper.dataset
    assert shown().n_cells == result.levels[0].mesh.n_faces
    labels = shown().cell_data["colours"].copy()
    box.level.value = len(result.levels) - 1
    assert shown().n_cells == result.levels[-1].mesh.n_faces and box.colour_by.value == "labels"
    box.colour_by.value = "confidence"  # the input level's only
    assert box.level.value == 0 and shown().n_cells == result.levels[0].mesh.n_faces
    assert not np.array_equal(shown().cell_data["colours"], labels)
    box.level.value = 1  # no confidence there: the labels
    assert box.colour_by.value == "labels" and shown().n_cells == result.levels[1].mesh.n_faces
    # framed: every point in view, the mesh filling the view's height or width but for the margin
    camera, points = plotter.camera, np.asarray(shown().points)
    ahead = np.subtract(camera.focal_point, camera.position)
    ahead /= np.linalg.norm(ahead)
    up = np.asarray(camera.up)
    right = np.cross(ahead, up)
    depth = (points - camera.position) @ ahead
    width, height = plotter.window_size
    tangent = max(np.abs((points - camera.position) @ right / depth).max() * height / width,
                  np.abs((points - camera.position) @ up / depth).max())
    assert 0.9 < tangent / np.tan(np.radians(camera.view_angle / 2)) < 1
    plotter.close()


def test_each_button_shows_a_panel():
    """A colouring keeps the level or takes the nearest it has; a level keeps the colouring or falls back on the labels."""
    keys = [("labels", 0), ("labels", 1), ("labels", 2), ("attention", 2), ("confidence", 0)]
    switches = viewer._switches(keys)
    assert switches[1] == {"kind": {"labels": 1, "attention": 3, "confidence": 4}, "level": {0: 0, 1: 1, 2: 2}}
    assert switches[3]["level"] == {0: 0, 1: 1, 2: 3} and switches[4]["level"] == {0: 4, 1: 1, 2: 2}
    assert all(switch["kind"][kind] == i and switch["level"][level] == i
               for i, (switch, (kind, level)) in enumerate(zip(switches, keys)))  # its own buttons keep a panel


def test_the_first_view_faces_the_widest_side_upright():
    from anseg.mesh import Mesh

    def box(sides):
        corners = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], dtype=float) * sides
        return Mesh(corners, np.array([[0, 1, 2], [3, 4, 5], [5, 6, 7]]))

    position, focal, up = viewer._front_view(box([0.8, 1.0, 0.4]))  # a teddy's proportions
    assert np.allclose(focal, [0.4, 0.5, 0.2])
    for sides, look, stand in [([0.8, 1.0, 0.4], [0, 0, 1], [0, 1, 0]),  # a teddy, standing on y as in PSB
                               ([0.8, 0.4, 1.6], [0, 1, 0], [0, 0, 1]),  # a figure standing on z, as the synthetic ones
                               ([1.6, 0.3, 0.4], [0, 1, 0], [0, 0, 1]),  # longest along x: lying, as x is never up
                               ([1.0, 0.5, 0.2], [0, 0, 1], [0, 1, 0]),  # a pair of glasses, level
                               ([0.5, 0.8, 0.9], [1, 0, 0], [0, 0, 1])]:  # a vase on z, seen from its side
        position, focal, up = viewer._front_view(box(sides))
        towards = np.subtract(position, focal)
        assert np.allclose(towards / np.linalg.norm(towards), look) and np.allclose(up, stand), sides


def _legend_notes(path) -> list[str]:
    import html

    return [html.unescape(note) for note in re.findall(r'<p class="anseg-note">(.*?)</p>', path.read_text())]


def _payload(path) -> int:
    """Characters of the scene vtk.js draws (base64 of its zipped arrays): the part of the page that grows with faces."""
    return len(re.search(r'const base64Str = "([^"]*)"', path.read_text()).group(1))


def _scene(path) -> dict:
    """The scene the page's vtk.js loads: its index.json, from the zip the page holds in base64."""
    import base64
    import io
    import json
    import zipfile

    archive = zipfile.ZipFile(io.BytesIO(base64.b64decode(re.search(r'const base64Str = "([^"]*)"', path.read_text()).group(1))))
    return json.loads(archive.read("index.json"))


def test_the_page_holds_each_levels_mesh_once(tmp_path):
    """The panels of one level colour one mesh: the file holds its points and triangles once, each panel's colours."""
    result = made_segmentation(n_levels=3)
    scene = _scene(viewer.write_html(result, ["a", "b"], tmp_path / "view.html"))
    [renderer] = scene["scene"]["dependencies"]
    actors = [d for d in renderer["dependencies"] if d["type"].endswith("Actor")]
    datasets = [d["dependencies"][0]["properties"] for a in actors for d in a["dependencies"]
                if d["type"].endswith("Mapper")]
    assert len(actors) == len(viewer.panels(result, 2)) == 3 + 3 + 1
    assert len({d["points"]["hash"] for d in datasets}) == len({d["polys"]["hash"] for d in datasets}) == 3
    assert len({d["fields"][0]["hash"] for d in datasets}) == len(actors)
    assert set(scene["hashes"]) == {d["points"]["hash"] for d in datasets} | {d["polys"]["hash"] for d in datasets} | {
        d["fields"][0]["hash"] for d in datasets}


def test_a_large_mesh_is_drawn_decimated_and_the_legend_says_so(tmp_path, monkeypatch):
    result = made_segmentation(subdivisions=4)  # 5120 faces, and 2560 on its coarser level
    full = viewer.write_html(result, ["a", "b"], tmp_path / "full.html")
    assert _legend_notes(full) == []
    monkeypatch.setattr(viewer, "DISPLAY_MAX_FACES", 2000)
    light = viewer.write_html(result, ["a", "b"], tmp_path / "light.html")
    [note] = _legend_notes(light)
    drawn, held = (int(n.replace(",", "")) for n in re.search(r"decimated to ([\d,]+) faces, of the ([\d,]+)", note).groups())
    assert drawn <= 2000 and held == 5120 + 2560  # each level's mesh counted once
    assert "5,120 with 1,000" in note  # the input mesh, as drawn on each of its three panels
    assert _payload(light) < _payload(full) / 3  # a quarter of the faces drawn
    assert len(result.labels) == result.levels[0].mesh.n_faces  # the data keep one label per input face

    # each drawn face has the colour of the input faces it covers: the label of its side of y = 0
    shown, _ = viewer._for_display(viewer.panels(result, 2), 2000)
    kind, level, mesh, rgb = shown[0]
    assert (kind, level, mesh.n_faces) == ("labels", 0, 1000)
    assert shown[len(result.levels)][2] is mesh  # the input mesh's attention: the same decimated mesh
    expected = palette(2)[sectors(mesh.face_centroids, 2)]
    assert (rgb == expected).all(axis=1).mean() > 0.95


def test_below_the_threshold_the_page_draws_every_face():
    result = made_segmentation(subdivisions=3)
    held = viewer.panels(result, 2)
    total = sum(level.mesh.n_faces for level in result.levels)  # each level's mesh once
    shown, note = viewer._for_display(held, total)
    assert note is None
    assert [(k, n, m, rgb) for k, n, m, rgb in shown] == [(k, n, m, rgb) for k, n, m, rgb in held]  # the same objects
    assert viewer._for_display(held, total - 1)[1] is not None
    # above it, the smaller meshes stay whole and the larger share the rest evenly
    assert viewer._face_cap([10, 100, 100], 110) == 50 and viewer._face_cap([10, 100], 110) is None


def test_a_panel_left_out_is_named_in_the_legend(tmp_path):
    """A uniform hierarchy segmented with combine="coarsest" holds attention on its last level only."""
    result = made_segmentation(n_levels=3, attention=[2], probabilities=False)
    assert len(viewer.panels(result, 2)) == 3 + 1  # the labels of each level, the last level's attention
    notes = _legend_notes(viewer.write_html(result, ["a", "b"], tmp_path / "view.html"))
    assert notes == ["No attention panel for levels 0, 1: the segmentation holds no attention there "
                     "(anseg.pipeline.fill_attention computes it).",
                     "No confidence panel: the segmentation holds no class probabilities."]
    assert viewer.missing_panels(made_segmentation()) == []
    # the input level of a mesh segmented through its collapse: no network read it, and fill_attention cannot help
    large = made_segmentation(subdivisions=6, n_levels=2, attention=[1])
    assert viewer.missing_panels(large) == ["No attention panel for level 0: no network reads it (a mesh above 60000 "
                                            "faces is segmented on its collapse, level 1, and the labels carried back)."]


def test_a_vertex_no_face_uses_does_not_shrink_the_panels():
    """The page frames each panel on its mesh's points: a stray far vertex would make the shape a dot."""
    result = made_segmentation(stray=True)
    shown, _ = viewer._for_display(viewer.panels(result, 2), viewer.DISPLAY_MAX_FACES)
    for _, _, mesh, rgb in shown:
        assert np.abs(mesh.vertices).max() < 1.01 and len(rgb) == mesh.n_faces


def test_panels_read_the_input_faces_where_the_levels_hold_them_in_another_order():
    """A canonical segmentation's levels hold the faces in the canonical order, a stray piece's the shape's alone:
    the panels colour each level face by the input face it is (Segmentation.level_faces), not by its position."""
    from dataclasses import replace

    made = made_segmentation(n_labels=3)
    level_face_of_input = np.random.default_rng(1).permutation(len(made.labels))  # input face j is level face p[j]
    shuffled = replace(made, labels=made.labels[level_face_of_input], probabilities=made.probabilities[level_face_of_input],
                       level_faces=np.argsort(level_face_of_input))
    panels = {(kind, index): rgb for kind, index, _, rgb in viewer.panels(shuffled, 3)}
    assert np.array_equal(panels["labels", 0], palette(3)[made.labels])
    unshuffled = {(kind, index): rgb for kind, index, _, rgb in viewer.panels(made, 3)}
    assert np.array_equal(panels["confidence", 0], unshuffled["confidence", 0])
