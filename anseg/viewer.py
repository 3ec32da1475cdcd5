"""A segmentation to look at and turn: one self-contained HTML file, or the same view in Jupyter.

Both show one mesh at a time, large: first the labels on the input mesh,
what a user came to see. A column beside it holds the legend and two rows
of buttons, one per colouring (labels, attention, confidence: the winning
class's probability) and one per level of the hierarchy (0 the input mesh,
each higher level a coarser one), so that every other view is one click
away (:func:`panels` lists them, :func:`_switches` says which one each
button shows). A view keeps the camera's direction when it changes and is
framed anew for its own mesh, so that the levels of one hierarchy compare
from where the user turned them; the first view looks at the input mesh's
widest side (:func:`_front_view`).

:func:`write_html` writes a page that opens in any browser with no server
and no network: pyvista's HTML export (vtk.js, embedded in the file) of one
scene that holds every panel, with the column and the script that switches
and frames the panels written into the page (the export drops text and
legends). A large mesh is drawn decimated, for display only
(:data:`DISPLAY_MAX_FACES`), and a panel the segmentation holds no data for
is named in the column with the reason (:func:`missing_panels`).
:func:`explore` is the live counterpart in a Jupyter session, through
pyvista's trame backend, with ipywidgets for the column.

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
from anseg.viz import _FIT_MARGIN, _place_camera, _pyvista, palette, polydata

# the most faces the page draws, each level's mesh counted once however many panels colour it (see write_html)
DISPLAY_MAX_FACES = 100_000
KEY = ("Level 0 is the input mesh, each higher level a coarser one. Attention: log scale, bright is high. "
       "Confidence (input mesh only): the winning class's probability, dark is low. "
       "Drag to turn, scroll to zoom; a click on a colouring or a level shows it from the same side.")
COLUMN_REM = 15  # the width of the column beside the view, in rem: the same whatever the font where it is used
_COLUMN = f"{COLUMN_REM}rem"
_VIEW_ANGLE = 30.0  # degrees, VTK's default, set again before each framing (which narrows it)


def panels(result, n_classes: int) -> list[tuple[str, int, Mesh, np.ndarray]]:
    """(colouring, level, mesh, per-face RGB uint8) of every view of a :class:`~anseg.pipeline.Segmentation`.

    The labels on each level first (the input mesh's is the first view),
    then each level's attention, then the confidence on the input mesh. A
    level without attention has no attention panel, and a result without
    probabilities no confidence panel: :func:`missing_panels` names them.
    """
    import matplotlib

    levels = result.levels
    colours = palette(n_classes)
    # the levels may hold the input's faces in another order or without its stray pieces: Segmentation.on_levels
    out = [("labels", index, level.mesh, colours[levels.labels_on(index, result.on_levels(result.labels), n_classes)])
           for index, level in enumerate(levels)]
    for index, level in enumerate(levels):
        if level.attention is not None:
            log = np.log(np.maximum(level.attention, 1e-6))
            low, high = np.percentile(log, [1, 99])
            # a flat attention (depth 0, or a level that collapses nothing) shows mid-scale, not black
            scaled = np.clip((log - low) / (high - low), 0, 1) if high - low > 1e-6 else np.full(len(log), 0.5)
            out.append(("attention", index, level.mesh, _rgb(matplotlib.colormaps["magma"](scaled))))
    if result.probabilities is not None:
        confidence = result.on_levels(result.probabilities).max(axis=1)
        out.append(("confidence", 0, levels[0].mesh, _rgb(matplotlib.colormaps["viridis"](confidence))))
    return out


def missing_panels(result) -> list[str]:
    """One line for each kind of panel the key promises that :func:`panels` cannot draw, and why.

    Attention exists only where the segmentation computed it: on the levels
    a nonuniform collapse started from and on those whose class probabilities
    it combined (``SegmentConfig.combine``); a uniform hierarchy combined at
    its coarsest level has it there alone. The viewer has no model to compute
    it with, so it says which levels lack it instead of leaving the button blank.
    """
    from anseg.pipeline import NETWORK_FACES

    notes = []
    first = result.levels[0]
    unread = first.attention is None and first.layout is None and first.mesh.n_faces > NETWORK_FACES
    if unread:  # segment's large-mesh path: no network reads the input level
        notes.append(f"No attention panel for level 0: no network reads it (a mesh above {NETWORK_FACES} faces is "
                     "segmented on its collapse, level 1, and the labels carried back).")
    bare = [str(index) for index, level in enumerate(result.levels) if level.attention is None and not (index == 0 and unread)]
    if bare:
        notes.append(f"No attention panel for level{'s' if len(bare) > 1 else ''} {', '.join(bare)}: the segmentation "
                     "holds no attention there (anseg.pipeline.fill_attention computes it).")
    if result.probabilities is None:
        notes.append("No confidence panel: the segmentation holds no class probabilities.")
    return notes


def _switches(keys: list[tuple[str, int]]) -> list[dict[str, dict]]:
    """For the panel of each (colouring, level) of ``keys``, the panel each button shows: {"kind": {colouring: index},
    "level": {level: index}}.

    A colouring's button keeps the level, or takes the nearest level that
    colouring has (the confidence exists on the input mesh alone); a level's
    button keeps the colouring where that level has it, else shows the labels,
    which every level has. So every button shows something, and a run of
    clicks on levels keeps comparing one colouring across the hierarchy.
    """
    index = {key: i for i, key in enumerate(keys)}
    levels = sorted({level for _, level in keys})
    out = []
    for kind, level in keys:
        by_kind = {}
        for other in dict.fromkeys(k for k, _ in keys):
            nearest = min((l for k, l in keys if k == other), key=lambda l: abs(l - level))
            by_kind[other] = index[(other, nearest)]
        out.append({"kind": by_kind, "level": {l: index.get((kind, l), index[("labels", l)]) for l in levels}})
    return out


def _front_view(mesh: Mesh) -> list[tuple[float, float, float]]:
    """The first camera (pyvista's [position, focal point, view up]): the mesh's widest side faces it, upright.

    The mesh's bounding box decides. The view looks along its shortest side,
    which makes the shape as large on the screen as an axis view can. Up is
    y or z, whichever of the two the view does not look along is longer:
    formats and data sets stand a shape on one of those (y in OBJ, glTF and
    most of PSB, z in CAD and in anseg's synthetic shapes), on x hardly ever,
    so that a pair of glasses lies level and a figure stands.
    """
    used = mesh.vertices[np.unique(mesh.faces)]  # a vertex no face uses is not the shape's
    low, high = used.min(axis=0), used.max(axis=0)
    towards = int(np.argmin(high - low))
    up = max((axis for axis in (1, 2) if axis != towards), key=lambda axis: high[axis] - low[axis])
    centre = (low + high) / 2
    return [tuple(centre + np.eye(3)[towards] * float(np.linalg.norm(high - low))), tuple(centre), tuple(np.eye(3)[up])]


def explore(result, label_names, jupyter_backend: str = "trame"):
    """A Jupyter widget: the view of :func:`write_html`'s page, a column with the legend and buttons beside the mesh.

    ``box.colour_by`` and ``box.level`` are the buttons (``box.plotter`` the
    plotter): setting their value is a click. ``jupyter_backend`` is
    pyvista's (``"trame"`` turns in the browser; the others are for tests
    and static output).
    """
    import ipywidgets

    pyvista = _pyvista()
    shown = panels(result, len(label_names))
    keys = [(kind, level) for kind, level, _, _ in shown]
    switches = _switches(keys)
    plotter = pyvista.Plotter(notebook=True)
    plotter.set_background("white")
    narrow = {"button_width": "auto"}
    colour_by = ipywidgets.ToggleButtons(options=list(dict.fromkeys(kind for kind, _ in keys)), style=narrow)
    level = ipywidgets.ToggleButtons(options=list(range(len(result.levels))), style=narrow)
    front = ipywidgets.Button(description="front view")
    current = [0]

    def show(index, camera=None):
        kind, number, mesh, rgb = shown[index]
        surface = polydata(mesh.without_unused_vertices())  # a stray vertex would set the camera's frame
        surface.cell_data["colours"] = rgb
        plotter.add_mesh(surface, scalars="colours", rgb=True, preference="cell", smooth_shading=False, name="mesh",
                         reset_camera=False)
        plotter.camera.view_angle = _VIEW_ANGLE
        _place_camera(plotter, camera or plotter.camera_position, surface.points)
        current[0] = index
        colour_by.value, level.value = kind, number  # their observers find the panel shown and do nothing
        plotter.render()
        if hasattr(view, "viewer"):  # the trame widget pushes the new scene to the browser
            view.viewer.update()

    view = None
    show(0, _front_view(shown[0][2]))
    with _without_vtk_wasm():
        view = plotter.show(jupyter_backend=jupyter_backend, return_viewer=True,
                            jupyter_kwargs={"width": "100%", "height": "80vh", "collapse_menu": True})

    def follow(buttons):
        """A click on one of ``buttons`` ("kind" or "level"): show the panel it leads to from the one shown."""
        def clicked(change):
            if (target := switches[current[0]][buttons][change.new]) != current[0]:
                show(target)
        return clicked

    colour_by.observe(follow("kind"), names="value")
    level.observe(follow("level"), names="value")
    front.on_click(lambda _: show(current[0], _front_view(shown[0][2])))
    notes = "".join(f'<p style="margin:.5em 0 0">{html.escape(note)}</p>' for note in missing_panels(result))
    side = ipywidgets.VBox([
        ipywidgets.HTML(f'<div style="font:13px sans-serif">{_swatches(label_names, result.labels)}</div>'),
        ipywidgets.Label("colour by"), colour_by, ipywidgets.Label("level"), level, front,
        ipywidgets.HTML(f'<div style="font:13px sans-serif;line-height:1.3"><p style="margin:.5em 0 0">{KEY}</p>{notes}</div>'),
    ], layout=ipywidgets.Layout(width=_COLUMN, flex="0 0 auto"))
    if isinstance(view, ipywidgets.Widget):
        view.layout.flex = "1 1 auto"
    box = ipywidgets.HBox([side, view] if isinstance(view, ipywidgets.Widget) else [side])
    box.plotter, box.colour_by, box.level, box.front = plotter, colour_by, level, front  # for callers and tests
    return box


def _rgb(rgba: np.ndarray) -> np.ndarray:
    return np.round(rgba[:, :3] * 255).astype(np.uint8)


def write_html(result, label_names, path: str | os.PathLike, title: str = "anseg segmentation") -> Path:
    """Write the page for ``result`` (what :func:`anseg.pipeline.segment` returns) to ``path``, atomically.

    The page's scene holds every panel of :func:`panels`, all but one
    hidden; its script (:data:`_SCRIPT`) shows the one a button asks for and
    frames it as :func:`anseg.viz._fit_view` does. The panels of one level
    share its mesh, which the file holds once (the export stores equal
    arrays once), so the page draws at most :data:`DISPLAY_MAX_FACES` faces
    counting each level's mesh once: every face drawn is written into the
    file, and the budget bounds its size whatever the number of levels.
    Above it, the largest meshes are decimated for display
    (:func:`_for_display`) and the column says so and to how many faces;
    ``result``, and every label written from it, stays one per input face.
    Panels that :func:`panels` cannot draw are named in the column
    (:func:`missing_panels`).
    """
    pyvista = _pyvista()
    shown, decimation = _for_display(panels(result, len(label_names)), DISPLAY_MAX_FACES)
    notes = missing_panels(result) + ([decimation] if decimation else [])
    plotter = pyvista.Plotter(off_screen=True)
    try:
        plotter.set_background("white")
        for _, _, mesh, rgb in shown:
            surface = polydata(mesh)
            surface.cell_data["colours"] = rgb
            plotter.add_mesh(surface, scalars="colours", rgb=True, preference="cell", smooth_shading=False)
        plotter.camera_position = _front_view(shown[0][2])
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
    data = {"panels": [{"kind": kind, "level": level} for kind, level, _, _ in shown],
            "switches": _switches([(kind, level) for kind, level, _, _ in shown]),
            "viewAngle": _VIEW_ANGLE, "margin": _FIT_MARGIN}
    script = "<script>" + _SCRIPT.replace("DATA", json.dumps(data)) + "</script>"
    body = page.index("<body>") + len("<body>")
    # the exported loader draws into the element of class "content" and empties it: the column stays beside it
    column = _column(label_names, result.labels, [kind for kind, _, _, _ in shown], len(result.levels), title, notes)
    page = page[:body] + column + '<div class="content" id="anseg-view"></div>' + page[body:]
    end = page.rindex("</body>")
    page = page[:end] + script + page[end:]
    return atomic_write(path, lambda tmp: tmp.write_text(page))


# The page's script. It waits for the exported loader to have built every panel (the actors come in the scene's order,
# that of panels()), then shows the first. show() hides every other panel, keeps the camera's direction and frames the
# panel's mesh as anseg.viz._fit_view does: VTK's reset to the bounding sphere from VTK's view angle, the view
# recentred on the projected points and the angle narrowed until every point is in view with a margin.
_SCRIPT = """(function () {
var data = DATA, renderWindow, renderer, actors, shown = -1, front;
function sub(a, b) { return [a[0] - b[0], a[1] - b[1], a[2] - b[2]]; }
function dot(a, b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
function unit(a) { var n = Math.sqrt(dot(a, a)); return [a[0] / n, a[1] / n, a[2] / n]; }
function cross(a, b) { return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]; }
function fit(actor) {
  var camera = renderer.getActiveCamera(), points = actor.getMapper().getInputData().getPoints().getData(), i, p;
  camera.setViewAngle(data.viewAngle);
  renderer.resetCamera(actor.getBounds());
  var position = camera.getPosition(), focal = camera.getFocalPoint(), ahead = unit(sub(focal, position));
  var right = unit(cross(ahead, camera.getViewUp())), up = cross(right, ahead);
  var lo = [Infinity, Infinity], hi = [-Infinity, -Infinity];
  for (i = 0; i < points.length; i += 3) {
    p = sub([points[i], points[i + 1], points[i + 2]], focal);
    lo = [Math.min(lo[0], dot(p, right)), Math.min(lo[1], dot(p, up))];
    hi = [Math.max(hi[0], dot(p, right)), Math.max(hi[1], dot(p, up))];
  }
  var across = (lo[0] + hi[0]) / 2, along = (lo[1] + hi[1]) / 2, shift;
  shift = [across * right[0] + along * up[0], across * right[1] + along * up[1], across * right[2] + along * up[2]];
  position = [position[0] + shift[0], position[1] + shift[1], position[2] + shift[2]];
  focal = [focal[0] + shift[0], focal[1] + shift[1], focal[2] + shift[2]];
  camera.setPosition(position[0], position[1], position[2]);
  camera.setFocalPoint(focal[0], focal[1], focal[2]);
  camera.setViewUp(up[0], up[1], up[2]);
  var size = renderWindow.getViews()[0].getSize(), tangent = 0, depth;
  for (i = 0; i < points.length; i += 3) {
    p = sub([points[i], points[i + 1], points[i + 2]], position);
    depth = Math.max(dot(p, ahead), 1e-9);
    tangent = Math.max(tangent, Math.abs(dot(p, right) / depth) * size[1] / size[0], Math.abs(dot(p, up) / depth));
  }
  camera.setViewAngle(2 * Math.atan(tangent * (1 + data.margin)) * 180 / Math.PI);
  renderer.resetCameraClippingRange();
}
function press(attribute, value) {
  document.querySelectorAll('#anseg-legend button[data-' + attribute + ']').forEach(function (button) {
    button.setAttribute('aria-pressed', String(button.dataset[attribute] === String(value)));
  });
}
function show(index) {
  actors.forEach(function (actor, i) { actor.setVisibility(i === index); });
  shown = index;
  fit(actors[index]);
  press('kind', data.panels[index].kind);
  press('level', data.panels[index].level);
  renderWindow.render();
  document.documentElement.dataset.ansegShown = data.panels[index].kind + ' ' + data.panels[index].level;
}
function loaded(actor) {
  var input = actor.getMapper() && actor.getMapper().getInputData();
  return input && input.getNumberOfPoints() > 0 && input.getNumberOfCells() > 0
    && input.getCellData().getArrayByName('colours');
}
function start() {
  renderWindow = window.global && window.global.renderWindow;
  // the scene's renderer, beside the empty one the loader's window starts with
  renderer = renderWindow && renderWindow.getRenderers().find(function (r) { return r.getActors().length; });
  actors = renderer ? renderer.getActors() : [];
  if (actors.length !== data.panels.length || !actors.every(loaded)) { setTimeout(start, 50); return; }
  var camera = renderer.getActiveCamera();
  front = [camera.getPosition(), camera.getFocalPoint(), camera.getViewUp()];
  document.getElementById('anseg-legend').addEventListener('click', function (event) {
    var button = event.target.closest('button'), camera = renderer.getActiveCamera();
    if (!button) return;
    if (button.dataset.kind) show(data.switches[shown].kind[button.dataset.kind]);
    else if (button.dataset.level) show(data.switches[shown].level[button.dataset.level]);
    else {
      camera.setPosition.apply(camera, front[0]);
      camera.setFocalPoint.apply(camera, front[1]);
      camera.setViewUp.apply(camera, front[2]);
      show(shown);
    }
  });
  show(0);
}
start();
})();"""


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


def _for_display(shown, budget: int) -> tuple[list[tuple[str, int, Mesh, np.ndarray]], str | None]:
    """The ``shown`` panels as the page draws them, and the column's line on their decimation (None without one).

    Every mesh loses the vertices no face uses: the page frames each panel on
    its mesh's points, and one stray point would shrink the shape to a dot.
    When the levels' meshes (each counted once, however many panels colour
    it) hold more than ``budget`` faces in all, each one larger than
    :func:`_face_cap`'s cap is drawn with that many faces (VTK's quadric
    decimation, once per mesh, so that the panels of one level stay alike),
    and each drawn face takes the colour of the face of the panel's own mesh
    whose centroid is nearest its own: the colours are the level's, only the
    triangles are fewer.
    """
    from scipy.spatial import cKDTree

    meshes = list({id(mesh): mesh for _, _, mesh, _ in shown}.values())
    cap = _face_cap([mesh.n_faces for mesh in meshes], budget)
    drawn = {}  # id(mesh): (the mesh drawn, the face of mesh that gives each drawn face its colour; None: every face)
    for mesh in meshes:
        drawn[id(mesh)] = (mesh.without_unused_vertices(), None)
        if cap is not None and mesh.n_faces > cap:
            surface = polydata(drawn[id(mesh)][0]).decimate(1 - cap / mesh.n_faces)
            light = Mesh(surface.points, surface.regular_faces).without_unused_vertices()
            drawn[id(mesh)] = light, cKDTree(mesh.face_centroids).query(light.face_centroids)[1]
    out = [(kind, level, drawn[id(mesh)][0], rgb if drawn[id(mesh)][1] is None else rgb[drawn[id(mesh)][1]])
           for kind, level, mesh, rgb in shown]
    if cap is None:
        return out, None
    first = meshes[0]
    return out, (f"Display decimated to {sum(drawn[id(m)][0].n_faces for m in meshes):,} faces, of the "
                 f"{sum(m.n_faces for m in meshes):,} the levels' meshes hold: each mesh of more than {cap:,} faces "
                 f"is drawn with about {cap:,} (the input mesh's {first.n_faces:,} with {drawn[id(first)][0].n_faces:,}), "
                 "each face in the colour of its level's nearest face. The labels written stay one per input face.")


def _face_cap(counts, budget: int) -> int | None:
    """The most faces a mesh may draw so that meshes of ``counts`` faces draw at most ``budget`` in all; None if all fit.

    The largest cap that fits: the meshes below it are drawn whole, and the
    others share evenly what those leave (taken smallest first, the first
    mesh larger than its even share of what is left sets the cap).
    """
    counts = np.sort(np.asarray(counts, dtype=np.int64))
    if counts.sum() <= budget:
        return None
    left = budget - np.concatenate([[0], np.cumsum(counts)[:-1]])
    shares = left // (len(counts) - np.arange(len(counts)))
    return int(shares[np.argmax(counts > shares)])


def _swatches(label_names, labels) -> str:
    """One line per label: its colour, its name (as text) and how many input faces it got."""
    counts = np.bincount(labels, minlength=len(label_names))
    return "".join(
        f'<div><span style="display:inline-block;width:1em;height:1em;margin-right:.4em;vertical-align:middle;'
        f'background:rgb({r},{g},{b})"></span>{html.escape(str(name))} ({count} faces)</div>'
        for name, (r, g, b), count in zip(label_names, palette(len(label_names)), counts))


_STYLE = ("<style>#anseg-legend{position:fixed;top:0;left:0;bottom:0;width:%s;box-sizing:border-box;overflow:auto;"
          "padding:8px 12px;font:13px sans-serif;border-right:1px solid #ddd;background:#fff;z-index:1000}"
          "#anseg-view{position:fixed;top:0;bottom:0;right:0;left:%s}#anseg-legend p{margin:.5em 0 0}"
          "#anseg-legend button{font:inherit;margin:2px 2px 0 0;padding:2px 7px;border:1px solid #999;border-radius:3px;"
          "background:#fff;cursor:pointer}#anseg-legend button[aria-pressed=true]{background:#333;border-color:#333;"
          "color:#fff}</style>") % (_COLUMN, _COLUMN)


def _column(label_names, labels, kinds, n_levels: int, title: str, notes) -> str:
    """The page's column beside the view: the title, the legend, a button per colouring in ``kinds`` and per level,
    the key and ``notes``."""
    def buttons(attribute, values):
        return "".join(f'<button type="button" data-{attribute}="{value}" aria-pressed="false">{value}</button>'
                       for value in values)

    return (f'{_STYLE}<div id="anseg-legend"><b>{html.escape(title)}</b>{_swatches(label_names, labels)}'
            f'<p>colour by<br>{buttons("kind", dict.fromkeys(kinds))}</p><p>level<br>{buttons("level", range(n_levels))}</p>'
            f'<p><button type="button" data-front="1">front view</button></p><p>{KEY}</p>'
            + "".join(f'<p class="anseg-note">{html.escape(note)}</p>' for note in notes) + "</div>")
