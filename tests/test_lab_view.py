"""The live view in a real JupyterLab, driven by headless Chromium: it draws the labels and follows its controls.

Starts a JupyterLab server on a free port with a notebook that segments a
mesh and shows :func:`anseg.viewer.explore` (pyvista's trame backend), opens
it in Chromium, runs it through JupyterLab's own command, and reads
screenshots over the DevTools protocol. The screenshots are kept in the
test's temporary folder (``lab_labels.png``, ``lab_attention.png``), or in
``$ANSEG_SCREENSHOTS`` when that is set. Nothing may leave the machine: in
Chromium, host names other than this machine's do not resolve, and in the
server's and the kernel's Python, an outside lookup or connection fails and is
logged; the test fails on any such attempt, by the page or by the kernel.
"""

from __future__ import annotations

import base64
import io
import json
import os
import socket
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

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

from anseg import datasets
from anseg.mesh_files import save_mesh
from anseg.pipeline import SegmentConfig, Segmenter, segment
from anseg.train import TrainConfig, fit
from anseg.viz import palette

pytestmark = [pytest.mark.slow, needs_chromium]
TOKEN = "anseg-test"
NOTEBOOK = """\
import torch
from anseg import viewer
from anseg.mesh_files import load_mesh
from anseg.pipeline import Segmenter, segment
torch.set_num_threads(1)
model = Segmenter.load("model.pt")
box = viewer.explore(segment(load_mesh("mesh.off"), model), model.label_names)
box"""
SWITCH = "slider, choice = box.children[0].children\nslider.value = slider.max\nchoice.value = 'attention'"


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _wait(check, seconds: float, what: str):
    end = time.time() + seconds
    while time.time() < end:
        if value := check():
            return value
        time.sleep(0.5)
    raise AssertionError(f"timed out after {seconds:.0f} s waiting for {what}")


class Browser:
    """Headless Chromium, one page, commands over the DevTools protocol."""

    def __init__(self, folder: Path):
        websocket = pytest.importorskip("websocket", reason="websocket-client (a JupyterLab dependency) is missing")
        profile = folder / "chromium"
        self.net_log = folder / "chromium.netlog.json"
        self.process = subprocess.Popen(
            headless_chromium(f"--log-net-log={self.net_log}", "--remote-debugging-port=0", f"--user-data-dir={profile}",
                              "--window-size=1400,1200", "about:blank"),
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        active = profile / "DevToolsActivePort"
        port = _wait(lambda: active.is_file() and active.read_text().split()[:1], 60, "Chromium's DevTools port")[0]
        pages = json.load(urllib.request.urlopen(f"http://127.0.0.1:{port}/json"))
        url = next(p for p in pages if p["type"] == "page")["webSocketDebuggerUrl"]
        self.socket = websocket.create_connection(url, timeout=60, suppress_origin=True)
        self.calls = 0

    def call(self, method: str, **params) -> dict:
        self.calls += 1
        self.socket.send(json.dumps({"id": self.calls, "method": method, "params": params}))
        while (message := json.loads(self.socket.recv())).get("id") != self.calls:
            pass  # an event
        return message.get("result", {})

    def js(self, expression: str):
        return self.call("Runtime.evaluate", expression=expression, returnByValue=True).get("result", {}).get("value")

    def screenshot(self) -> np.ndarray:
        from PIL import Image

        png = base64.b64decode(self.call("Page.captureScreenshot", format="png")["data"])
        return np.asarray(Image.open(io.BytesIO(png)).convert("RGB"))

    def close(self):
        self.socket.send(json.dumps({"id": 0, "method": "Browser.close"}))  # a clean exit completes the net log
        self.socket.close()
        try:
            self.process.wait(timeout=30)
        except subprocess.TimeoutExpired:
            self.process.kill()


@pytest.fixture(scope="module")
def lab(tmp_path_factory):
    """A JupyterLab serving a folder with the notebook, a trained model and a mesh; the labels it must show."""
    pytest.importorskip("jupyterlab", reason="JupyterLab is not installed (pip install -e '.[notebooks]')")
    torch.set_num_threads(1)
    folder = tmp_path_factory.mktemp("lab")
    shapes = datasets.load("synthetic", category="figure", split="all", n_shapes=5, progress=False)
    model = fit(shapes[:3], shapes[0].label_names, SegmentConfig(cycles=2, clusters=4), TrainConfig(epochs=3, width=16),
                progress=False)
    model.save(folder / "model.pt")
    save_mesh(folder / "mesh.off", shapes[4].mesh)
    labels = segment(shapes[4].mesh, Segmenter.load(folder / "model.pt")).labels
    cells = [{"cell_type": "code", "metadata": {}, "outputs": [], "execution_count": None, "source": source}
             for source in (NOTEBOOK, SWITCH)]
    (folder / "view.ipynb").write_text(json.dumps({
        "cells": cells, "nbformat": 4, "nbformat_minor": 5,
        "metadata": {"kernelspec": {"name": "python3", "display_name": "Python 3", "language": "python"}}}))
    port = _free_port()
    offline, attempts = offline_python(folder)
    private = {name: str(folder / name.lower()) for name in
               ("JUPYTER_DATA_DIR", "JUPYTERLAB_SETTINGS_DIR", "JUPYTERLAB_WORKSPACES_DIR", "JUPYTER_RUNTIME_DIR")}
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
        _wait(up, 120, "the JupyterLab server")
        yield folder, port, model.label_names, labels, attempts
    finally:
        server.terminate()
        server.wait(timeout=30)


def _keep(name: str, picture: np.ndarray, folder: Path) -> Path:
    from PIL import Image

    out = screenshot_folder(folder)
    Image.fromarray(picture).save(out / name)
    return out / name


def _colour_hits(picture: np.ndarray, box: dict, colours: np.ndarray) -> list[int]:
    """How many pixels of the view's box lie near each colour (lighting shades a face's colour)."""
    x, y, w, h = (int(box[k]) for k in ("x", "y", "width", "height"))
    pixels = picture[y:y + h, x:x + w].reshape(-1, 3).astype(int)
    return [int((np.abs(pixels - colour).sum(axis=1) < 60).sum()) for colour in colours]


def _screenshot_when(browser: Browser, test, seconds: float, what: str, folder: Path) -> np.ndarray:
    """The first screenshot that passes ``test``, taken every half second; on a timeout the last one is kept."""
    taken = []

    def passes():
        taken[:] = [browser.screenshot()]
        return test(taken[0])

    try:
        _wait(passes, seconds, what)
    except AssertionError as error:  # _wait checks at least once, so a screenshot was taken
        raise AssertionError(f"{error}; the last screenshot: {_keep('lab_timeout.png', taken[0], folder)}") from None
    return taken[0]


def test_the_view_turns_in_jupyterlab_and_follows_its_controls(lab):
    folder, port, names, labels, attempts = lab
    browser = Browser(folder)
    try:
        browser.call("Page.navigate", url=f"http://127.0.0.1:{port}/lab/tree/view.ipynb?token={TOKEN}")
        # the notebook's panel in the main area (headless, no widget has the focus: shell.currentWidget is null)
        panel = "Array.from(window.jupyterapp.shell.widgets('main')).find(w => w.sessionContext)"
        kernel_idle = (f"(() => {{ const w = window.jupyterapp && {panel}; const s = w && w.sessionContext.session;"
                       " return !!(s && s.kernel && s.kernel.status === 'idle'); })()")
        _wait(lambda: browser.js(kernel_idle), 180, "the notebook's kernel")
        browser.js(f"window.jupyterapp.shell.activateById(({panel}).id); true")
        browser.js("window.jupyterapp.commands.execute('notebook:run-cell-and-select-next'); true")  # the view
        view = ("(() => { const f = document.querySelector('.jp-OutputArea iframe');"
                " return f && f.getBoundingClientRect().width > 100 ? f.getBoundingClientRect().toJSON() : null; })()")
        box = _wait(lambda: browser.js(view), 300, "the view's frame in the output")
        used = palette(len(names))[np.unique(labels)]
        drawn = _screenshot_when(browser, lambda picture: max(_colour_hits(picture, box, used)) > 500, 300,
                                 "the mesh drawn in its label colours", folder)
        before = sum(_colour_hits(drawn, box, used))
        _keep("lab_labels.png", drawn, folder)
        legend = browser.js("document.querySelector('.jp-OutputArea').innerText")
        assert all(name in legend for name in names) and "Level 0 is the input mesh" in legend
        browser.js("window.jupyterapp.commands.execute('notebook:run-cell'); true")  # coarsest level, attention
        switched = _screenshot_when(browser, lambda picture: sum(_colour_hits(picture, box, used)) < before / 5, 300,
                                    "the view to leave the label colours for the attention", folder)
        _keep("lab_attention.png", switched, folder)
        x, y, w, h = (int(box[k]) for k in ("x", "y", "width", "height"))
        assert switched[y:y + h, x:x + w].std() > 10, "a blank view after the switch"
    finally:
        browser.close()
    requested = page_requests(browser.net_log, "http://127.0.0.1")
    assert requested and not off_machine(requested), f"the page asked for {off_machine(requested)}"
    assert not attempts.exists(), f"the server or the kernel tried to reach {attempts.read_text().split()}"
