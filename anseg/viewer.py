"""A segmentation to look at and turn: one self-contained HTML file, or a view with a level slider in Jupyter.

:func:`write_html` writes a page that opens in any browser with no server and
no network. The page holds every level of the hierarchy side by side: the top row the
labels on the input mesh and on each coarser level, then the confidence
(the winning class's probability); the bottom row each level's attention.
The 3D view is pyvista's HTML export (vtk.js, embedded in the file); that
export drops text and legends, so the legend and the key to the rows are
written into the page itself. A large mesh is drawn decimated, for display
only (:data:`DISPLAY_MAX_FACES`), and a panel the segmentation holds no data
for is named in the legend with the reason (:func:`missing_panels`).
:func:`explore` is the live counterpart in a
Jupyter session: one mesh at a time, a slider for the level and a choice of
labels, attention or confidence, through pyvista's trame backend.

Neither needs a network: both draw with vtk.js, which trame-vtk ships in its
wheel, and VTK on the Python side (see :func:`_without_vtk_wasm`).
"""

from __future__ import annotations

import contextlib
import html
import json
import os
import re
import sys
from pathlib import Path

import numpy as np

from anseg.cache import atomic_write
from anseg.mesh import Mesh
from anseg.viz import _pyvista, palette, polydata

_GAP = 1.5  # between panels, in units of a panel's size (each mesh scaled to unit bounding-box diagonal)
# the most faces the page draws, all panels together (see write_html)
DISPLAY_MAX_FACES = 100_000


def panels(result, n_classes: int) -> list[tuple[int, int, Mesh, np.ndarray]]:
    """(row, column, mesh, per-face RGB uint8) of every panel of the page for a :class:`~anseg.pipeline.Segmentation`.

    A level without attention has no attention panel, and a result without
    probabilities no confidence panel: :func:`missing_panels` names them.
    """
    import matplotlib

    levels = result.levels
    colours = palette(n_classes)
    out = []
    for index, level in enumerate(levels):
        labels = levels.labels_on(index, result.labels, n_classes)
        out.append((0, index, level.mesh, colours[labels]))
        if level.attention is not None:
            log = np.log(np.maximum(level.attention, 1e-6))
            low, high = np.percentile(log, [1, 99])
            # a flat attention (depth 0, or a level that collapses nothing) shows mid-scale, not black
            scaled = np.clip((log - low) / (high - low), 0, 1) if high - low > 1e-6 else np.full(len(log), 0.5)
            out.append((1, index, level.mesh, _rgb(matplotlib.colormaps["magma"](scaled))))
    if result.probabilities is not None:
        confidence = result.probabilities.max(axis=1)
        out.append((0, len(levels), levels[0].mesh, _rgb(matplotlib.colormaps["viridis"](confidence))))
    return out


def missing_panels(result) -> list[str]:
    """One line for each kind of panel the key promises that :func:`panels` cannot draw, and why.

    Attention exists only where the segmentation computed it: on the levels
    a nonuniform collapse started from and on those whose class probabilities
    it combined (``SegmentConfig.combine``); a uniform hierarchy combined at
    its coarsest level has it there alone. The viewer has no model to compute
    it with, so it says which levels lack it instead of leaving gaps in the row.
    """
    notes = []
    bare = [str(index) for index, level in enumerate(result.levels) if level.attention is None]
    if bare:
        notes.append(f"No attention panel for level{'s' if len(bare) > 1 else ''} {', '.join(bare)}: the segmentation "
                     "holds no attention there (anseg.pipeline.fill_attention computes it).")
    if result.probabilities is None:
        notes.append("No confidence panel: the segmentation holds no class probabilities.")
    return notes


COLOURINGS = ("labels", "attention", "confidence")
WIDGET_KEY = ("Level 0 is the input mesh, each higher level a coarser one. Attention: log scale, bright is high. "
              "Confidence (input mesh only): the winning class's probability, dark is low. Drag to turn, scroll to zoom.")


def explore(result, label_names, jupyter_backend: str = "trame"):
    """A Jupyter widget: the mesh of one level, coloured by ``COLOURINGS``, a level slider and a legend.

    The confidence exists on the input level only (the slider is then set
    there). ``jupyter_backend`` is pyvista's (``"trame"`` turns in the
    browser; the others are for tests and static output).
    """
    import ipywidgets

    pyvista = _pyvista()
    colours = {(kind, column): (mesh, rgb) for kind, column, mesh, rgb in _by_kind(result, len(label_names))}
    plotter = pyvista.Plotter(notebook=True)
    plotter.set_background("white")
    slider = ipywidgets.IntSlider(value=0, min=0, max=len(result.levels) - 1, description="level")
    choice = ipywidgets.Dropdown(options=COLOURINGS, value="labels", description="colour by")

    def show(*_):
        kind = choice.value
        if kind == "confidence":
            slider.value = 0
        mesh, rgb = colours.get((kind, slider.value), colours[("labels", slider.value)])
        surface = polydata(mesh.without_unused_vertices())  # a stray vertex would set the camera's frame
        surface.cell_data["colours"] = rgb
        plotter.clear_actors()
        plotter.add_mesh(surface, scalars="colours", rgb=True, preference="cell", smooth_shading=False, name="mesh")
        plotter.render()
        if hasattr(view, "viewer"):  # the trame widget pushes the new scene to the browser
            view.viewer.update()

    view = None
    show()
    with _without_vtk_wasm():
        view = plotter.show(jupyter_backend=jupyter_backend, return_viewer=True)
    slider.observe(show, names="value")
    choice.observe(show, names="value")
    notes = "".join(f'<p style="margin:.5em 0 0">{html.escape(note)}</p>' for note in missing_panels(result))
    legend = ipywidgets.HTML(f'<div style="font:13px sans-serif;max-width:22em">{_swatches(label_names, result.labels)}'
                             f'<p style="margin:.5em 0 0">{WIDGET_KEY}</p>{notes}</div>')
    box = ipywidgets.VBox([ipywidgets.HBox([slider, choice]), ipywidgets.HBox([legend, view])
                           if isinstance(view, ipywidgets.Widget) else legend])
    box.plotter = plotter  # for callers that update or close it
    return box


def _by_kind(result, n_classes: int):
    """:func:`panels` keyed by what colours them: (kind, level, mesh, rgb)."""
    kinds = {0: "labels", 1: "attention"}
    for row, column, mesh, rgb in panels(result, n_classes):
        if column == len(result.levels):  # the confidence, on the input mesh
            yield "confidence", 0, mesh, rgb
        else:
            yield kinds[row], column, mesh, rgb


def _rgb(rgba: np.ndarray) -> np.ndarray:
    return np.round(rgba[:, :3] * 255).astype(np.uint8)


def write_html(result, label_names, path: str | os.PathLike, title: str = "anseg segmentation") -> Path:
    """Write the page for ``result`` (what :func:`anseg.pipeline.segment` returns) to ``path``, atomically.

    The page draws at most :data:`DISPLAY_MAX_FACES` faces, all panels
    together: every face drawn is written into the file, while a panel, a
    fraction of a browser window, shows a shape and the outlines of its
    segments as well with some thousands of faces as with more, and that
    budget leaves each of the eleven panels of a five-level hierarchy that
    many. The budget is per page, not per panel, so that the file's size is
    bounded whatever the number of levels. Above it, the largest panels are
    decimated for display (:func:`_for_display`) and the legend says so and
    to how many faces; ``result``, and every label written from it, stays
    one per input face. Panels that :func:`panels` cannot draw are named in
    the legend (:func:`missing_panels`).
    """
    pyvista = _pyvista()
    shown, decimation = _for_display(panels(result, len(label_names)), DISPLAY_MAX_FACES)
    notes = missing_panels(result) + ([decimation] if decimation else [])
    plotter = pyvista.Plotter(off_screen=True)
    try:
        plotter.set_background("white")
        for row, column, mesh, rgb in shown:
            surface = polydata(_unit(mesh))
            surface.translate((column * _GAP, -row * _GAP, 0.0), inplace=True)
            surface.cell_data["colours"] = rgb
            plotter.add_mesh(surface, scalars="colours", rgb=True, preference="cell", smooth_shading=False)
        plotter.view_xy()
        scratch = Path(path).with_name(f".{Path(path).name}.export.html")
        with _without_vtk_wasm():
            plotter.trame.export_html(str(scratch))
    finally:
        plotter.close()
    try:
        page = scratch.read_text()
    finally:
        scratch.unlink(missing_ok=True)
    page = page.replace("<title>VTK.js | Example - OfflineLocalView</title>", f"<title>{html.escape(title)}</title>")
    page = _offline(page)
    # the viewer empties <body> when it starts, so the legend is added beside it once the page has loaded
    legend = json.dumps(_legend(label_names, result.labels, len(result.levels), title, notes)).replace("</", "<\\/")
    script = ("<script>window.addEventListener('load', function () { var box = document.createElement('div'); "
              f"box.innerHTML = {legend}; document.documentElement.appendChild(box.firstChild); }});</script>")
    head = page.index("</head>")
    page = page[:head] + script + page[head:]
    return atomic_write(path, lambda tmp: tmp.write_text(page))


@contextlib.contextmanager
def _without_vtk_wasm():
    """Launch pyvista's trame server as if trame-vtklocal were not installed.

    trame-pyvista enables trame-vtklocal (VTK compiled to WebAssembly) on the
    server it launches whenever it can import it, and that module's setup
    downloads VTK's WebAssembly build for the installed VTK from
    gitlab.kitware.com. Our views never use it (the live one draws with VTK
    and vtk.js, the page with vtk.js), so the download is only a network
    request: offline it fails, and its traceback lands in the notebook cell,
    or on stderr, every time. With the module hidden from ``import`` while the
    server starts, trame-pyvista skips it, as it does wherever it cannot
    import it. Once started, the server serves every later view of the
    process, so the first launch is the one that counts.
    """
    import trame.widgets

    name = "trame.widgets.vtklocal"
    module, attribute = sys.modules.get(name), trame.widgets.__dict__.pop("vtklocal", None)
    sys.modules[name] = None  # an import of it raises ImportError, which trame-pyvista skips
    try:
        yield
    finally:
        if module is None:
            del sys.modules[name]
        else:
            sys.modules[name] = module
        if attribute is not None:
            trame.widgets.vtklocal = attribute


# the page may fetch nothing from anywhere: scripts, styles and images come inline (or as data:/blob: URLs)
_NO_FETCH = ("<meta http-equiv=\"Content-Security-Policy\" content=\"default-src 'none'; "
             "script-src 'unsafe-inline' 'unsafe-eval'; style-src 'unsafe-inline'; img-src data: blob:; "
             "font-src data:; connect-src data: blob:; worker-src blob:\">")


def _offline(page: str) -> str:
    """The exported page, made to request nothing off this machine.

    vtk.js adds five favicon links to kitware.github.io when it loads; they
    become empty ``data:`` icons. The Content-Security-Policy tells the
    browser to fetch nothing that is not in the page, so whatever a later
    vtk.js adds fails at once instead of reaching out.
    """
    page = re.sub(r"https?://[^\s\"'`]*/favicon[^\s\"'`]*", "data:,", page)
    head = page.index("<head>") + len("<head>")
    return page[:head] + _NO_FETCH + page[head:]


def _for_display(shown, budget: int) -> tuple[list[tuple[int, int, Mesh, np.ndarray]], str | None]:
    """The ``shown`` panels as the page draws them, and the legend's line on their decimation (None without one).

    Every mesh loses the vertices no face uses: the page scales each panel to
    its bounding box, and one stray point would shrink the shape to a dot.
    When the panels hold more than ``budget`` faces in all, each one larger
    than :func:`_face_cap`'s cap is drawn with that many faces (VTK's quadric
    decimation, once per mesh, so that the panels of one level stay alike),
    and each drawn face takes the colour of the face of the panel's own mesh
    whose centroid is nearest its own: the colours are the level's, only the
    triangles are fewer.
    """
    from scipy.spatial import cKDTree

    cap = _face_cap([mesh.n_faces for _, _, mesh, _ in shown], budget)
    drawn = {}  # id(mesh): (the mesh drawn, the face of mesh that gives each drawn face its colour; None: every face)
    out = []
    for row, column, mesh, rgb in shown:
        if id(mesh) not in drawn:
            drawn[id(mesh)] = (mesh.without_unused_vertices(), None)
            if cap is not None and mesh.n_faces > cap:
                surface = polydata(drawn[id(mesh)][0]).decimate(1 - cap / mesh.n_faces)
                light = Mesh(surface.points, surface.regular_faces).without_unused_vertices()
                drawn[id(mesh)] = light, cKDTree(mesh.face_centroids).query(light.face_centroids)[1]
        light, source = drawn[id(mesh)]
        out.append((row, column, light, rgb if source is None else rgb[source]))
    if cap is None:
        return out, None
    first = shown[0][2]
    return out, (f"Display decimated to {sum(m.n_faces for _, _, m, _ in out):,} faces, of the "
                 f"{sum(m.n_faces for _, _, m, _ in shown):,} the panels hold: each panel of more than {cap:,} faces "
                 f"is drawn with about {cap:,} (the input mesh's {first.n_faces:,} with {drawn[id(first)][0].n_faces:,}), "
                 "each face in the colour of its level's nearest face. The labels written stay one per input face.")


def _face_cap(counts, budget: int) -> int | None:
    """The most faces a panel may draw so that panels of ``counts`` faces draw at most ``budget`` in all; None if all fit.

    The largest cap that fits: the panels below it are drawn whole, and the
    others share evenly what those leave (taken smallest first, the first
    panel larger than its even share of what is left sets the cap).
    """
    counts = np.sort(np.asarray(counts, dtype=np.int64))
    if counts.sum() <= budget:
        return None
    left = budget - np.concatenate([[0], np.cumsum(counts)[:-1]])
    shares = left // (len(counts) - np.arange(len(counts)))
    return int(shares[np.argmax(counts > shares)])


def _unit(mesh: Mesh) -> Mesh:
    """The mesh centred and scaled to a bounding-box diagonal of 1, so panels of any size sit on one grid."""
    low, high = mesh.vertices.min(axis=0), mesh.vertices.max(axis=0)
    size = max(float(np.linalg.norm(high - low)), 1e-12)
    return Mesh((mesh.vertices - (low + high) / 2) / size, mesh.faces)


def _swatches(label_names, labels) -> str:
    """One line per label: its colour, its name (as text) and how many input faces it got."""
    counts = np.bincount(labels, minlength=len(label_names))
    return "".join(
        f'<div><span style="display:inline-block;width:1em;height:1em;margin-right:.4em;vertical-align:middle;'
        f'background:rgb({r},{g},{b})"></span>{html.escape(str(name))} ({count} faces)</div>'
        for name, (r, g, b), count in zip(label_names, palette(len(label_names)), counts))


def _legend(label_names, labels, n_levels: int, title: str, notes) -> str:
    """The page's legend: a box pinned to its top left corner, with the key to its rows of panels and ``notes`` below."""
    key = (f"Top row, left to right: the labels on the input mesh and on each of the {n_levels - 1} coarser levels, "
           "then the confidence (the winning class's probability; dark is low). Bottom row: each level's attention "
           "(log scale; bright is high). Drag to turn, scroll to zoom.")
    return (f'<div id="anseg-legend" style="position:fixed;top:8px;left:8px;z-index:1000;background:rgba(255,255,255,.9);'
            f'padding:8px 12px;font:13px sans-serif;max-width:24em;border-radius:4px">'
            f"<b>{html.escape(title)}</b>{_swatches(label_names, labels)}<p style=\"margin:.5em 0 0\">{key}</p>"
            + "".join(f'<p class="anseg-note" style="margin:.5em 0 0">{html.escape(note)}</p>' for note in notes) + "</div>")
