"""The standalone HTML view: self-contained, with its legend, and drawn in the label colours by a real browser."""

from __future__ import annotations

import re
import shutil
import subprocess

import numpy as np
import pytest
import torch

from anseg import datasets, viewer
from anseg.pipeline import SegmentConfig, segment
from anseg.train import TrainConfig, fit
from anseg.viz import palette

CHROMIUM = next((shutil.which(name) for name in ("chromium", "chromium-browser", "google-chrome") if shutil.which(name)), None)


@pytest.fixture(scope="module")
def page(tmp_path_factory):
    torch.set_num_threads(1)
    shapes = datasets.load("synthetic", category="figure", split="all", n_shapes=5, progress=False)
    model = fit(shapes[:3], shapes[0].label_names, SegmentConfig(cycles=2, clusters=4), TrainConfig(epochs=3, width=16),
                progress=False)
    result = segment(shapes[4].mesh, model)
    path = tmp_path_factory.mktemp("view") / "view.html"
    names = [*model.label_names[:-1], "<b>&odd</b>"]  # a label name is text, never markup
    viewer.write_html(result, names, path, title="figure")
    return path, result, names


def test_the_page_is_self_contained_with_a_legend(page):
    path, result, names = page
    text = path.read_text()
    assert not re.search(r"<(script|link|img)[^>]+(src|href)=[\"']https?://", text)  # nothing fetched from a network
    assert "&lt;b&gt;&amp;odd&lt;/b&gt;" in text and "<b>&odd</b>" not in text
    assert text.count("coarser levels") == 1
    n_panels = len(viewer.panels(result, len(names)))
    assert n_panels == 2 * len(result.levels) + 1  # labels and attention per level, and the confidence


@pytest.mark.skipif(CHROMIUM is None, reason="no Chromium installed (Debian: apt-get install chromium)")
def test_a_browser_draws_the_mesh_in_the_label_colours(page, tmp_path):
    from PIL import Image

    path, result, names = page
    shot = tmp_path / "shot.png"
    subprocess.run([CHROMIUM, "--headless=new", "--no-sandbox", "--use-gl=swiftshader", "--enable-unsafe-swiftshader",
                    "--virtual-time-budget=8000", "--window-size=1200,800", f"--screenshot={shot}", path.as_uri()],
                   capture_output=True, timeout=120, check=True)
    pixels = np.asarray(Image.open(shot).convert("RGB")).reshape(-1, 3).astype(int)
    assert (pixels.std(axis=0) > 10).all(), "a blank page"
    used = palette(len(names))[np.unique(result.labels)]
    # lighting shades a face's colour, so look for pixels near the hue of a predicted label, in the 3D view's area
    lower_half = np.asarray(Image.open(shot).convert("RGB"))[250:].reshape(-1, 3).astype(int)
    hits = [int((np.abs(lower_half - colour).sum(axis=1) < 60).sum()) for colour in used]
    assert max(hits) > 200, f"no label colour drawn: {hits}"


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
