"""What the viewer's tests share: a segmentation made by hand, headless Chromium driven over the DevTools protocol,
and what a screenshot of a view must show (how much of the window the mesh covers, which label colours it shows)."""

from __future__ import annotations

import base64
import io
import json
import subprocess
import time
import urllib.request
from pathlib import Path

import numpy as np
import pytest
from conftest import headless_chromium, screenshot_folder

WINDOW = (1400, 900)  # the browser tests' window, in CSS pixels


def sectors(points: np.ndarray, n: int) -> np.ndarray:
    """The label of each point: which of ``n`` equal sectors about the z axis holds it (two: the sign of y)."""
    return (np.floor((np.arctan2(points[:, 1], points[:, 0]) + np.pi) / (2 * np.pi) * n) % n).astype(np.int64)


def made_segmentation(subdivisions: int = 3, n_levels: int = 2, attention=True, probabilities=True, stray=False,
                      n_labels: int = 2, flatten: float = 1.0):
    """A Segmentation built by hand, no model: an icosphere labelled by :func:`sectors`, with uniform collapses.

    ``attention``: True for every level, or the levels that get one; ``stray``: a far vertex that no face uses;
    ``flatten``: the sphere's height along z (1: a sphere), so that the view looks along z and sees every sector.
    """
    import trimesh

    from anseg import collapse
    from anseg.hierarchy import Hierarchy, Level
    from anseg.mesh import Mesh
    from anseg.pipeline import Segmentation

    sphere = trimesh.creation.icosphere(subdivisions)
    vertices = sphere.vertices * [1.0, 1.0, flatten]
    mesh = Mesh(np.vstack([vertices, [[1e6, -1e6, 1e6]]]) if stray else vertices, sphere.faces)
    rng = np.random.default_rng(0)
    levels, current = [], mesh
    for index in range(n_levels):
        has_attention = attention is True or index in attention
        levels.append(Level(current, {}, None, attention=rng.uniform(0.1, 1.0, current.n_faces) if has_attention else None))
        if index < n_levels - 1:
            current, levels[-1].record = collapse.downsample(current, None, ratio=0.5, mode="uniform")
    labels = sectors(mesh.face_centroids, n_labels)
    probs = None
    if probabilities:
        probs = np.full((len(labels), n_labels), 0.2 / (n_labels - 1))
        probs[np.arange(len(labels)), labels] = 0.8
    return Segmentation(labels=labels, probabilities=probs, unsmoothed_labels=labels, levels=Hierarchy(levels))


def wait(check, seconds: float, what: str):
    """The first true value of ``check()``, tried every half second; AssertionError after ``seconds``."""
    end = time.time() + seconds
    while time.time() < end:
        if value := check():
            return value
        time.sleep(0.5)
    raise AssertionError(f"timed out after {seconds:.0f} s waiting for {what}")


class Browser:
    """Headless Chromium, one page of :data:`WINDOW` CSS pixels, commands over the DevTools protocol.

    Its net log lands in ``folder`` (``net_log``), complete once :meth:`close` returns.
    """

    def __init__(self, folder: Path):
        websocket = pytest.importorskip("websocket", reason="websocket-client (a JupyterLab dependency) is missing")
        profile = folder / "chromium"
        self.net_log = folder / "chromium.netlog.json"
        self.process = subprocess.Popen(
            headless_chromium(f"--log-net-log={self.net_log}", "--remote-debugging-port=0", f"--user-data-dir={profile}",
                              f"--window-size={WINDOW[0]},{WINDOW[1]}", "about:blank"),
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        active = profile / "DevToolsActivePort"
        try:
            port = wait(lambda: active.is_file() and active.read_text().split()[:1], 60, "Chromium's DevTools port")[0]
            pages = json.load(urllib.request.urlopen(f"http://127.0.0.1:{port}/json"))
            url = next(p for p in pages if p["type"] == "page")["webSocketDebuggerUrl"]
            self.socket = websocket.create_connection(url, timeout=60, suppress_origin=True)
        except BaseException:  # no browser left behind by a test that could not reach it
            self.process.kill()
            raise
        self.calls = 0
        # the page gets the whole window (a headless window keeps some of its height for a frame it does not draw)
        self.call("Emulation.setDeviceMetricsOverride", width=WINDOW[0], height=WINDOW[1], deviceScaleFactor=1, mobile=False)

    def call(self, method: str, **params) -> dict:
        self.calls += 1
        self.socket.send(json.dumps({"id": self.calls, "method": method, "params": params}))
        while (message := json.loads(self.socket.recv())).get("id") != self.calls:
            pass  # an event
        return message.get("result", {})

    def js(self, expression: str):
        return self.call("Runtime.evaluate", expression=expression, returnByValue=True).get("result", {}).get("value")

    def box(self, selector: str) -> tuple[int, int, int, int] | None:
        """(x, y, width, height) of the first element ``selector`` finds, in the window; None while there is none."""
        rect = self.js(f"(() => {{ const e = document.querySelector({json.dumps(selector)});"
                       " return e && e.getBoundingClientRect().toJSON(); })()")
        return rect and tuple(int(round(rect[k])) for k in ("x", "y", "width", "height"))

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


def keep(name: str, picture: np.ndarray, folder: Path) -> Path:
    """Save ``picture`` as ``name`` in the screenshot folder (``$ANSEG_SCREENSHOTS``, else ``folder``)."""
    from PIL import Image

    path = screenshot_folder(folder) / name
    Image.fromarray(picture).save(path)
    return path


def screenshot_when(browser: Browser, test, seconds: float, what: str, folder: Path) -> np.ndarray:
    """The first screenshot that passes ``test``, taken every half second; on a timeout the last one is kept."""
    taken = []

    def passes():
        taken[:] = [browser.screenshot()]
        return test(taken[0])

    try:
        wait(passes, seconds, what)
    except AssertionError as error:  # wait checks at least once, so a screenshot was taken
        raise AssertionError(f"{error}; the last screenshot: {keep('timeout.png', taken[0], folder)}") from None
    return taken[0]


def _drawn(picture: np.ndarray, box) -> np.ndarray:
    """The pixels of ``box`` that are not the views' white background (antialiased rims included)."""
    x, y, w, h = box
    view = picture[max(y, 0):y + h, max(x, 0):x + w].reshape(-1, 3).astype(int)
    return view[(255 - view).sum(axis=1) > 30]


def window_share(picture: np.ndarray, box) -> float:
    """The share of the whole window (``picture``) that the view in ``box`` draws its mesh on."""
    return len(_drawn(picture, box)) / (picture.shape[0] * picture.shape[1])


def label_hits(picture: np.ndarray, box, labels: np.ndarray, n_names: int) -> dict[int, int]:
    """How many pixels of the view in ``box`` show each label of ``labels``, by colour.

    White lights scale a face's colour, they keep its direction in RGB: a
    pixel shows the palette colour nearest its own in direction, when it
    lies within 4 degrees of it, less than half the angle between any two of
    tab10's colours (the palette up to 10 labels).
    """
    from anseg.viz import palette

    colours = palette(n_names).astype(float)
    pixels = _drawn(picture, box).astype(float)
    cosine = (pixels @ colours.T) / (np.linalg.norm(pixels, axis=1)[:, None] * np.linalg.norm(colours, axis=1) + 1e-9)
    nearest = np.where(cosine.max(axis=1) > np.cos(np.radians(4)), cosine.argmax(axis=1), -1)
    return {int(label): int((nearest == label).sum()) for label in np.unique(labels)}
