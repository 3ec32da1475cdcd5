"""Pictures for the notebooks: offscreen mesh renders (pyvista) and the paper's plots (matplotlib).

* :func:`render` draws one mesh, flat-shaded per face, coloured by a label
  per face (a qualitative palette, :func:`label_colors`) or by a scalar per
  face (a colour map, e.g. the attention heat maps of the paper's Fig. 4),
  seen from a fixed direction with the camera fitted to the bounds, so that
  the levels of one hierarchy come out framed alike.
* :func:`render_panel` puts several renders side by side with titles and an
  optional label legend (:func:`legend_handles`) or colour bar.
* :func:`line_plot` (Fig. 11: accuracy against cycles, one line per ratio)
  and :func:`bar_plot` (Fig. 12: grouped bars per category and feature set).

pyvista is imported on first use only (it pulls in VTK). Rendering is always
offscreen; unless the caller chose a VTK window class, EGL is used, which
needs no display server. Every figure function writes a PNG and returns the
matplotlib Figure, left open so that a notebook shows it; scripts should
close it (``plt.close(fig)``).
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from pathlib import Path

import matplotlib
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.patches import Patch

CAMERAS = ("iso", "front", "side", "top")
# reset_camera frames the bounding sphere, which leaves a wide margin around most shapes
_ZOOM = 1.25
_BACKGROUND = "white"
_UNLABELLED_GREY = (0.8, 0.8, 0.8)
_DPI = 120


# ---------------------------------------------------------------- colours
def palette(n_classes: int) -> np.ndarray:
    """(n_classes, 3) uint8 distinct colours: tab10 up to 10 classes, tab20 up to 20, evenly spaced hues beyond."""
    if n_classes < 1:
        raise ValueError(f"n_classes must be at least 1, got {n_classes}")
    if n_classes <= 10:
        rgb = matplotlib.colormaps["tab10"].colors[:n_classes]
    elif n_classes <= 20:
        # tab20 pairs a strong and a pale shade of each hue: take all strong ones first
        colours = matplotlib.colormaps["tab20"].colors
        rgb = (list(colours[0::2]) + list(colours[1::2]))[:n_classes]
    else:
        rgb = matplotlib.colormaps["hsv"](np.linspace(0.0, 1.0, n_classes, endpoint=False))[:, :3]
    return np.round(np.asarray(rgb, dtype=float) * 255).astype(np.uint8)


def label_colors(labels, n_classes: int) -> np.ndarray:
    """(F, 3) uint8 colour of every face from its 0-based label; ValueError for a label outside [0, n_classes)."""
    labels = np.asarray(labels)
    if labels.ndim != 1 or not np.issubdtype(labels.dtype, np.integer):
        raise ValueError(f"labels must be a 1-D integer array, got shape {labels.shape} and dtype {labels.dtype}")
    if len(labels) and (labels.min() < 0 or labels.max() >= n_classes):
        raise ValueError(f"labels span [{labels.min()}, {labels.max()}], outside [0, {n_classes})")
    return palette(n_classes)[labels]


def legend_handles(label_names: Sequence[str]) -> list[Patch]:
    """Matplotlib legend entries, one per label, in the colours :func:`label_colors` gives."""
    colours = palette(len(label_names)) / 255.0
    return [Patch(facecolor=tuple(c), edgecolor="black", linewidth=0.5, label=name) for name, c in zip(label_names, colours)]


# ---------------------------------------------------------------- renders
def _pyvista():
    """pyvista, set up for offscreen rendering (EGL unless the caller picked another VTK window)."""
    os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
    import pyvista

    pyvista.OFF_SCREEN = True
    return pyvista


def polydata(mesh):
    """``mesh`` (anything with ``vertices`` and ``faces``) as a pyvista PolyData, e.g. for an interactive plotter."""
    pyvista = _pyvista()
    faces = np.asarray(mesh.faces, dtype=np.int64)
    cells = np.column_stack([np.full(len(faces), 3, dtype=np.int64), faces]).ravel()
    return pyvista.PolyData(np.asarray(mesh.vertices, dtype=float), cells)


def _place_camera(plotter, camera) -> None:
    if isinstance(camera, str):
        if camera not in CAMERAS:
            raise ValueError(f"camera must be one of {CAMERAS} or a pyvista camera position, got {camera!r}")
        {"iso": plotter.view_isometric, "front": plotter.view_xz, "side": plotter.view_yz, "top": plotter.view_xy}[camera]()
    else:
        plotter.camera_position = camera
    plotter.reset_camera()  # fit the view to the bounds
    plotter.camera.zoom(_ZOOM)


def render(
    mesh,
    face_scalars=None,
    labels=None,
    n_classes: int | None = None,
    cmap: str = "Reds",
    camera="iso",
    window_size: tuple[int, int] = (600, 600),
    clim: tuple[float, float] | None = None,
) -> np.ndarray:
    """An RGB image (H, W, 3) uint8 of ``mesh`` (anything with ``vertices`` and ``faces``), flat-shaded per face.

    Colour the faces by ``labels`` (0-based, ``n_classes`` of them: the
    qualitative palette of :func:`label_colors`) or by ``face_scalars``
    through ``cmap`` with limits ``clim`` (default: the values' range); with
    neither, plain grey. ``camera`` is one of :data:`CAMERAS` (``"iso"``: an
    isometric view; ``"front"``, ``"side"``, ``"top"``: along y, x, z) or a
    pyvista camera position; the view is always fitted to the mesh's bounds.
    """
    if face_scalars is not None and labels is not None:
        raise ValueError("colour by face_scalars or by labels, not both")
    n_faces = len(mesh.faces)
    pyvista = _pyvista()
    surface = polydata(mesh)
    plotter = pyvista.Plotter(off_screen=True, window_size=list(window_size))
    try:
        plotter.set_background(_BACKGROUND)
        style = {"show_edges": False, "smooth_shading": False, "lighting": True}
        if labels is not None:
            if n_classes is None:
                raise ValueError("labels need n_classes, so that a label keeps its colour from render to render")
            colours = label_colors(labels, n_classes)
            if len(colours) != n_faces:
                raise ValueError(f"{len(colours)} labels for {n_faces} faces")
            surface.cell_data["colours"] = colours
            plotter.add_mesh(surface, scalars="colours", rgb=True, preference="cell", **style)
        elif face_scalars is not None:
            values = np.asarray(face_scalars, dtype=float)
            if values.shape != (n_faces,):
                raise ValueError(f"face_scalars of shape {values.shape}, expected ({n_faces},)")
            surface.cell_data["values"] = values
            plotter.add_mesh(surface, scalars="values", cmap=cmap, clim=clim, preference="cell",
                             show_scalar_bar=False, **style)
        else:
            plotter.add_mesh(surface, color=_UNLABELLED_GREY, **style)
        _place_camera(plotter, camera)
        image = plotter.screenshot(return_img=True)
    finally:
        plotter.close()
    return np.asarray(image)[..., :3]


# ---------------------------------------------------------------- figures
def _save(fig, path) -> None:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=_DPI, bbox_inches="tight", facecolor="white")


def render_panel(
    images: Sequence[np.ndarray],
    titles: Sequence[str],
    path,
    legend: Sequence[Patch] | None = None,
    colorbar: Mapping | None = None,
    title: str | None = None,
    ncols: int | None = None,
):
    """Renders side by side (``ncols`` per row, default all in one row), each with its title; saved as a PNG at ``path``.

    ``legend``: label entries from :func:`legend_handles`, drawn below the
    images. ``colorbar``: ``{"cmap": ..., "vmin": ..., "vmax": ..., "label": ...}``
    for scalar renders (the same limits the renders used).
    """
    if len(images) != len(titles) or not images:
        raise ValueError(f"need one title per image and at least one image; got {len(images)} images and {len(titles)} titles")
    ncols = ncols or len(images)
    nrows = -(-len(images) // ncols)
    # a colour bar gets a thin row of its own under the images, so that it never covers one
    heights = [1.0] * nrows + ([0.08] if colorbar is not None else [])
    fig = plt.figure(figsize=(3.2 * ncols, 3.4 * nrows + (0.5 if colorbar is not None else 0.0)))
    grid = fig.add_gridspec(len(heights), ncols, height_ratios=heights)
    for index, (image, text) in enumerate(zip(images, titles)):
        ax = fig.add_subplot(grid[index // ncols, index % ncols])
        ax.imshow(image)
        ax.set_title(text, fontsize=10)
        ax.axis("off")
    if title:
        fig.suptitle(title, fontsize=12)
    if colorbar is not None:
        host = fig.add_subplot(grid[-1, :])
        host.axis("off")
        mappable = plt.cm.ScalarMappable(
            norm=matplotlib.colors.Normalize(colorbar["vmin"], colorbar["vmax"]), cmap=colorbar.get("cmap", "Reds"))
        bar = fig.colorbar(mappable, cax=host.inset_axes([0.2, 0.0, 0.6, 1.0]), orientation="horizontal")
        bar.set_label(colorbar.get("label", ""))
    if legend:
        fig.legend(handles=list(legend), loc="lower center", ncol=min(len(legend), 8), frameon=False,
                   bbox_to_anchor=(0.5, -0.02), fontsize=9)
    _save(fig, path)
    return fig


def label_panel(
    views: Sequence[tuple],
    label_names: Sequence[str],
    path,
    title: str | None = None,
    ncols: int | None = None,
    camera="iso",
    window_size: tuple[int, int] = (500, 500),
):
    """Segmentations side by side: ``views`` are ``(mesh, title, labels)``; one legend for ``label_names``; a PNG at ``path``.

    E.g. ground truth beside a prediction (the paper's Figs. 5-10), one mesh
    per row with ``ncols`` = 2.
    """
    n_classes = len(label_names)
    images = [render(mesh, labels=labels, n_classes=n_classes, camera=camera, window_size=window_size)
              for mesh, _, labels in views]
    return render_panel(images, [text for _, text, _ in views], path, legend=legend_handles(label_names),
                        title=title, ncols=ncols)


def line_plot(
    x: Sequence[float],
    series: Mapping[str, Sequence[float]],
    path,
    xlabel: str,
    ylabel: str,
    title: str | None = None,
    legend_title: str | None = None,
    bands: Mapping[str, Sequence[float]] | None = None,
):
    """One coloured line with markers per entry of ``series`` (name -> y over ``x``), saved as a PNG at ``path``.

    Missing values (NaN) leave gaps. The paper's Fig. 11: x the number of
    cycles, one line per downsampling ratio, y the accuracy. ``bands`` (name ->
    a half-width per x, e.g. the standard deviation over splits) shades y ± it.
    """
    if not series:
        raise ValueError("no series to plot")
    fig, ax = plt.subplots(figsize=(6.0, 4.0))
    colours = palette(len(series)) / 255.0
    for (name, ys), colour in zip(series.items(), colours):
        ys = np.asarray(ys, dtype=float)
        if ys.shape != (len(x),):
            raise ValueError(f"series {name!r} has {ys.size} values for {len(x)} x positions")
        ax.plot(x, ys, marker="o", color=tuple(colour), label=str(name))
        if bands is not None and name in bands:
            half = np.asarray(bands[name], dtype=float)
            ax.fill_between(x, ys - half, ys + half, color=tuple(colour), alpha=0.15, linewidth=0)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_xticks(list(x))
    ax.grid(alpha=0.3)
    if title:
        ax.set_title(title)
    ax.legend(title=legend_title, frameon=False, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    _save(fig, path)
    return fig


def bar_plot(
    groups: Sequence[str],
    series: Mapping[str, Sequence[float]],
    path,
    xlabel: str,
    ylabel: str,
    title: str | None = None,
    legend_title: str | None = None,
    ylim: tuple[float, float] | None = None,
    errors: Mapping[str, Sequence[float]] | None = None,
):
    """Grouped bars: one group per entry of ``groups`` (x), one coloured bar per entry of ``series`` (name -> value per group).

    Saved as a PNG at ``path``. The paper's Fig. 12: groups are categories,
    series the feature sets, values the accuracy. ``errors`` (name -> one
    value per group, e.g. the standard deviation over splits) draws error bars.
    """
    if not series or not groups:
        raise ValueError("need at least one group and one series")
    fig, ax = plt.subplots(figsize=(max(5.0, 1.2 * len(groups) * len(series) ** 0.5 + 2.0), 4.0))
    width = 0.8 / len(series)
    centres = np.arange(len(groups))
    colours = palette(len(series)) / 255.0
    for i, ((name, values), colour) in enumerate(zip(series.items(), colours)):
        values = np.asarray(values, dtype=float)
        if values.shape != (len(groups),):
            raise ValueError(f"series {name!r} has {values.size} values for {len(groups)} groups")
        spread = None if errors is None else np.asarray(errors[name], dtype=float)
        bars = ax.bar(centres + (i - (len(series) - 1) / 2) * width, values, width, color=tuple(colour), label=str(name),
                      yerr=spread, capsize=3 if spread is not None else 0)
        ax.bar_label(bars, fmt="%.1f", fontsize=7, padding=1)
    ax.set_xticks(centres, list(groups))
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    if ylim is not None:
        ax.set_ylim(*ylim)
    ax.grid(axis="y", alpha=0.3)
    if title:
        ax.set_title(title)
    ax.legend(title=legend_title, frameon=False, fontsize=9, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    _save(fig, path)
    return fig
