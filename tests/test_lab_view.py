"""The live view in a real JupyterLab, driven by headless Chromium: the labelled mesh large, and it follows its buttons.

Starts a JupyterLab server on a free port with a notebook that shows
:func:`anseg.viewer.explore` (pyvista's trame backend) for a segmentation
made by hand (a flattened sphere in five labelled sectors), opens it in a
1400 x 900 Chromium window with JupyterLab's file browser folded away, runs
it through JupyterLab's own command, and reads screenshots over the DevTools
protocol. The screenshots are kept in the test's temporary folder
(``lab_labels.png``, ``lab_attention.png``), or in ``$ANSEG_SCREENSHOTS`` when
that is set. Nothing may leave the machine: in Chromium, host names other
than this machine's do not resolve, and in the server's and the kernel's
Python, an outside lookup or connection fails and is logged; the test fails
on any such attempt, by the page or by the kernel.
"""

from __future__ import annotations

import json
import os
import pickle
import socket
import subprocess
import sys
import urllib.request
from pathlib import Path

import pytest
from conftest import needs_chromium, off_machine, offline_python, page_requests
from viewing import Browser, keep, label_hits, made_segmentation, screenshot_when, wait, window_share

pytestmark = [pytest.mark.slow, needs_chromium]
TOKEN = "anseg-test"
NAMES = ["one", "two", "three", "four", "five"]
NOTEBOOK = """\
import pickle
from anseg import viewer
with open("segmentation.pkl", "rb") as file:
    result, names = pickle.load(file)
box = viewer.explore(result, names)
box"""
SWITCH = "box.level.value = box.level.options[-1]\nbox.colour_by.value = 'attention'"


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture(scope="module")
def lab(tmp_path_factory):
    """A JupyterLab serving a folder with the notebook and the segmentation it shows; the labels it must show."""
    pytest.importorskip("jupyterlab", reason="JupyterLab is not installed (pip install -e '.[notebooks]')")
    folder = tmp_path_factory.mktemp("lab")
    result = made_segmentation(subdivisions=4, n_levels=3, n_labels=len(NAMES), flatten=0.6)
    (folder / "segmentation.pkl").write_bytes(pickle.dumps((result, NAMES)))
    cells = [{"cell_type": "code", "metadata": {}, "outputs": [], "execution_count": None, "source": source}
             for source in (NOTEBOOK, SWITCH)]
    (folder / "view.ipynb").write_text(json.dumps({
        "cells": cells, "nbformat": 4, "nbformat_minor": 5,
        "metadata": {"kernelspec": {"name": "python3", "display_name": "Python 3", "language": "python"}}}))
    port = _free_port()
    offline, attempts = offline_python(folder)
    private = {name: str(folder / name.lower()) for name in
               ("JUPYTER_DATA_DIR", "JUPYTERLAB_SETTINGS_DIR", "JUPYTERLAB_WORKSPACES_DIR", "JUPYTER_RUNTIME_DIR")}
    # no toast asking about Jupyter's news, which would lie over the view; once that is answered JupyterLab asks PyPI
    # for a newer version of itself, unless told not to
    news = Path(private["JUPYTERLAB_SETTINGS_DIR"]) / "@jupyterlab" / "apputils-extension" / "notification.jupyterlab-settings"
    news.parent.mkdir(parents=True)
    news.write_text(json.dumps({"fetchNews": "false", "checkForUpdates": False}))
    server = subprocess.Popen(
        [sys.executable, "-m", "jupyterlab", "--no-browser", f"--port={port}", "--ServerApp.ip=127.0.0.1",
         f"--IdentityProvider.token={TOKEN}", f"--ServerApp.root_dir={folder}", "--LabApp.expose_app_in_browser=True",
         "--allow-root"],
        stdout=(folder / "lab.log").open("w"), stderr=subprocess.STDOUT,
        env={**os.environ, **private, **offline, "OMP_NUM_THREADS": "1"})

    def up():
        try:
            return urllib.request.urlopen(f"http://127.0.0.1:{port}/api/status?token={TOKEN}", timeout=5).status == 200
        except OSError:
            return False

    try:
        wait(up, 120, "the JupyterLab server")
        yield folder, port, result.labels, attempts
    finally:
        server.terminate()
        server.wait(timeout=30)


def test_the_view_shows_the_labelled_mesh_large_in_jupyterlab_and_follows_its_buttons(lab):
    folder, port, labels, attempts = lab
    browser = Browser(folder)
    try:
        browser.call("Page.navigate", url=f"http://127.0.0.1:{port}/lab/tree/view.ipynb?token={TOKEN}")
        # the notebook's panel in the main area (headless, no widget has the focus: shell.currentWidget is null)
        panel = "Array.from(window.jupyterapp.shell.widgets('main')).find(w => w.sessionContext)"
        kernel_idle = (f"(() => {{ const w = window.jupyterapp && {panel}; const s = w && w.sessionContext.session;"
                       " return !!(s && s.kernel && s.kernel.status === 'idle'); })()")
        wait(lambda: browser.js(kernel_idle), 180, "the notebook's kernel")
        browser.js(f"window.jupyterapp.shell.collapseLeft(); window.jupyterapp.shell.activateById(({panel}).id); true")
        browser.js("window.jupyterapp.commands.execute('notebook:run-cell-and-select-next'); true")  # the view
        frame = ".jp-OutputArea iframe"
        wait(lambda: (box := browser.box(frame)) and box[2] > 100, 300, "the view's frame in the output")
        browser.js(f"document.querySelector('{frame}').scrollIntoView({{block: 'center'}}); true")
        box = browser.box(frame)
        hits = lambda picture: label_hits(picture, box, labels, len(NAMES))  # noqa: E731
        drawn = screenshot_when(browser, lambda picture: min(hits(picture).values()) > 1000, 300,
                                "the mesh drawn in every label colour", folder)
        keep("lab_labels.png", drawn, folder)
        assert window_share(drawn, box) >= 0.25, f"the mesh covers {window_share(drawn, box):.1%} of the window"
        before = sum(hits(drawn).values())
        legend = browser.js("document.querySelector('.jp-OutputArea').innerText")
        assert all(name in legend for name in NAMES) and "Level 0 is the input mesh" in legend
        browser.js("window.jupyterapp.commands.execute('notebook:run-cell'); true")  # coarsest level, attention
        switched = screenshot_when(browser, lambda picture: sum(hits(picture).values()) < before / 5, 300,
                                   "the view to leave the label colours for the attention", folder)
        keep("lab_attention.png", switched, folder)
        assert window_share(switched, box) >= 0.25, "the coarsest level's attention covers too little of the window"
    finally:
        browser.close()
    requested = page_requests(browser.net_log, "http://127.0.0.1")
    assert requested and not off_machine(requested), f"the page asked for {off_machine(requested)}"
    assert not attempts.exists(), f"the server or the kernel tried to reach {attempts.read_text().split()}"
