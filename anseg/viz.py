"""Pictures for the notebooks: offscreen mesh renders (pyvista) and the paper's plots (matplotlib).

* :func:`render` draws one mesh, flat-shaded per face, coloured by a label
  per face (a qualitative palette, :func:`label_colors`) or by a scalar per
  face (a colour map, e.g. the attention heat maps of the paper's Fig. 4),
  seen from a fixed direction with the view fitted to the mesh (nothing
  clipped), so that the levels of one hierarchy come out framed alike.
* :func:`render_panel` puts several renders side by side with titles and an
  optional label legend (:func:`legend_handles`) or colour bar.
* :func:`bar_plot` (Fig. 12: grouped bars per category and feature set).
* :func:`paper_beside_ours` (Table IV: the paper's value beside ours with
  whiskers, one panel per category), :func:`line_panels` (Fig. 11: small
  multiples with a band) and :func:`segmentation_rows` (Figs. 5-8: meshes
  of several categories, each row with its own legend).

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

CAMERAS = ("iso", "iso_y_up", "front", "side", "top")
_Y_UP = [(1.0, 0.8, 1.6), (0.0, 0.0, 0.0), (0.0, 1.0, 0.0)]  # an oblique view of a mesh whose up axis is y (COSEG)
# reset_camera frames the bounding sphere, which leaves a wide margin around most shapes
_ZOOM = 1.25
_FIT_MARGIN = 0.04  # the share of the view left free around a fitted mesh
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


def _place_camera(plotter, camera, points=None) -> None:
    if isinstance(camera, str):
        if camera not in CAMERAS:
            raise ValueError(f"camera must be one of {CAMERAS} or a pyvista camera position, got {camera!r}")
        if camera == "iso_y_up":
            plotter.camera_position = _Y_UP
        else:
            {"iso": plotter.view_isometric, "front": plotter.view_xz, "side": plotter.view_yz,
             "top": plotter.view_xy}[camera]()
    else:
        plotter.camera_position = camera
    plotter.reset_camera()  # frame the bounding sphere
    if points is None or len(points) == 0:
        plotter.camera.zoom(_ZOOM)
    else:
        _fit_view(plotter, np.asarray(points, dtype=float))


def _fit_view(plotter, points: np.ndarray) -> None:
    """Centre the view on the projected points and narrow it until every point is in view with a margin of _FIT_MARGIN.

    Zooming the bounding sphere by a fixed factor clips long shapes seen along
    a diagonal; fitting the projection itself never does.
    """
    camera = plotter.camera
    position, focal = np.asarray(camera.position, float), np.asarray(camera.focal_point, float)
    ahead = focal - position
    ahead /= np.linalg.norm(ahead)
    right = np.cross(ahead, np.asarray(camera.up, float))
    right /= np.linalg.norm(right)
    up = np.cross(right, ahead)
    across, along = (points - focal) @ right, (points - focal) @ up
    shift = 0.5 * (across.max() + across.min()) * right + 0.5 * (along.max() + along.min()) * up
    position, focal = position + shift, focal + shift
    camera.position, camera.focal_point, camera.up = tuple(position), tuple(focal), tuple(up)
    depth = np.maximum((points - position) @ ahead, 1e-9)
    width, height = plotter.window_size
    tangent = max(np.abs((points - position) @ right / depth).max() * height / width,
                  np.abs((points - position) @ up / depth).max())
    camera.view_angle = float(np.degrees(2 * np.arctan(tangent * (1 + _FIT_MARGIN))))
    plotter.reset_camera_clipping_range()


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
    isometric view, z up; ``"iso_y_up"``: an oblique view, y up; ``"front"``, ``"side"``, ``"top"``: along y, x, z) or a
    pyvista camera position; the view is always fitted to the mesh, so that none of it is clipped.
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
        _place_camera(plotter, camera, surface.points)
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
    caption: str | None = None,
):
    """Renders side by side (``ncols`` per row, default all in one row), each with its title; saved as a PNG at ``path``.

    ``legend``: label entries from :func:`legend_handles`, drawn below the
    images. ``colorbar``: ``{"cmap": ..., "vmin": ..., "vmax": ..., "label": ...}``
    for scalar renders (the same limits the renders used). ``caption``: text under it all.
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
    if caption:
        fig.text(0.02, -0.06 if legend else 0.0, caption, ha="left", va="top", fontsize=8.5, wrap=True)
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
    caption: str | None = None,
):
    """Segmentations side by side: ``views`` are ``(mesh, title, labels)``; one legend for ``label_names``; a PNG at ``path``.

    E.g. ground truth beside a prediction (the paper's Figs. 5-10), one mesh
    per row with ``ncols`` = 2.
    """
    n_classes = len(label_names)
    images = [render(mesh, labels=labels, n_classes=n_classes, camera=camera, window_size=window_size)
              for mesh, _, labels in views]
    return render_panel(images, [text for _, text, _ in views], path, legend=legend_handles(label_names),
                        title=title, ncols=ncols, caption=caption)


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


def _caption(fig, caption: str | None) -> None:
    if caption:
        fig.text(0.01, -0.01, caption, ha="left", va="top", fontsize=8.5, wrap=True)


def paper_beside_ours(
    groups: Sequence[str],
    rows: Sequence[str],
    ours: Mapping[str, Mapping[str, float]],
    spread: Mapping[str, Mapping[str, float]],
    paper: Mapping[str, Mapping[str, float]],
    path,
    ylabel: str,
    title: str | None = None,
    caption: str | None = None,
    margin: float = 1.5,
):
    """One panel per group (e.g. a category), one pair of bars per row: the paper's value (hatched) beside ours.

    ``ours[row][group]`` with whiskers of half-width ``spread[row][group]``
    (e.g. the standard deviation over splits); ``paper[row][group]``, missing
    where the paper has no such row (the slot then says so). The y axis is
    shared and zoomed to the values and whiskers (``margin`` points around
    them), not started at 0. A PNG at ``path``; ``caption`` goes under the panels.
    """
    if not groups or not rows:
        raise ValueError("need at least one group and one row")
    def value(table, row, group):
        return float(table.get(row, {}).get(group, np.nan))
    # a spread that is not there (one split: NaN) draws no whisker and widens nothing
    shown = [value(ours, r, g) + s * np.nan_to_num(value(spread, r, g)) for r in rows for g in groups for s in (-1, 1)]
    shown += [value(paper, r, g) for r in rows for g in groups]
    shown = np.asarray([v for v in shown if np.isfinite(v)])
    if not len(shown):
        raise ValueError("no finite value to draw")
    low, high = shown.min() - margin, min(shown.max() + margin, 100.0 + margin / 2)
    fig, axes = plt.subplots(1, len(groups), figsize=(1.0 + 2.4 * len(groups) * max(1.0, len(rows) / 4), 3.8),
                             sharey=True, squeeze=False)
    colours = {"paper": (0.75, 0.75, 0.75), "ours": tuple(palette(1)[0] / 255.0)}
    width, centres = 0.38, np.arange(len(rows))
    for ax, group in zip(axes[0], groups):
        for offset, who in ((-width / 2, "paper"), (width / 2, "ours")):
            heights = np.array([value(paper if who == "paper" else ours, r, group) for r in rows])
            errors = None if who == "paper" else np.nan_to_num([value(spread, r, group) for r in rows])
            drawn = np.where(np.isfinite(heights), heights, low)
            bars = ax.bar(centres + offset, drawn - low, width, bottom=low, color=colours[who],
                          hatch="///" if who == "paper" else None, edgecolor="white" if who == "paper" else None,
                          yerr=errors, capsize=3, label=who if group == groups[0] else None)
            for bar, height in zip(bars, heights):
                x = bar.get_x() + bar.get_width() / 2
                if np.isfinite(height):
                    ax.text(x, low + 0.3, f"{height:.1f}", ha="center", va="bottom", fontsize=7, rotation=90,
                            color="black", bbox={"facecolor": "white", "edgecolor": "none", "pad": 0.6, "alpha": 0.85})
                else:
                    ax.text(x, low + 0.3, "not in paper", ha="center", va="bottom", fontsize=7, rotation=90,
                            color="dimgray")
        ax.set_xticks(centres, [r.replace(", ", ",\n") for r in rows], fontsize=8)
        ax.set_title(group)
        ax.set_ylim(low, high)
        ax.grid(axis="y", alpha=0.3)
    axes[0][0].set_ylabel(ylabel)
    fig.legend(*axes[0][0].get_legend_handles_labels(), loc="upper right", frameon=False, ncol=2, fontsize=9,
               bbox_to_anchor=(1.0, 1.0))
    if title:
        fig.suptitle(title, x=0.01, ha="left", fontsize=11)
    fig.tight_layout()
    _caption(fig, caption)
    _save(fig, path)
    return fig


def line_panels(
    x: Sequence[float],
    panels: Mapping[str, tuple[Sequence[float], Sequence[float], Sequence[float]]],
    path,
    xlabel: str,
    ylabel: str,
    title: str | None = None,
    caption: str | None = None,
    mark: tuple[str, float] | None = None,
    mark_label: str = "",
    ncols: int | None = None,
):
    """Small multiples: one panel per entry of ``panels`` (title -> (mean, low, high) over ``x``), a shared y axis.

    Each panel draws the mean as a line with markers and shades the band from
    ``low`` to ``high`` (say in ``caption`` what it is). ``mark`` = (panel
    title, x) rings that point, e.g. the paper's chosen setting. A PNG at ``path``.
    """
    if not panels:
        raise ValueError("no panels to plot")
    ncols = ncols or min(len(panels), 5)
    nrows = -(-len(panels) // ncols)
    fig, axes = plt.subplots(nrows, ncols, figsize=(max(4.8, 0.6 + 2.6 * ncols), 0.6 + 2.6 * nrows), sharey=True,
                             sharex=True, squeeze=False)
    colour, marked = tuple(palette(1)[0] / 255.0), None
    for ax, (name, (mean, low, high)) in zip(axes.flat, panels.items()):
        mean, low, high = (np.asarray(v, dtype=float) for v in (mean, low, high))
        if not mean.shape == low.shape == high.shape == (len(x),):
            raise ValueError(f"panel {name!r}: need one mean, low and high per x position ({len(x)})")
        ax.fill_between(x, low, high, color=colour, alpha=0.2, linewidth=0)
        ax.plot(x, mean, marker="o", markersize=4, color=colour)
        if mark is not None and mark[0] == name and mark[1] in list(x):
            at = list(x).index(mark[1])
            marked = ax.plot([mark[1]], [mean[at]], marker="o", markersize=13, markerfacecolor="none",
                             markeredgecolor="crimson", markeredgewidth=2, linestyle="none", label=mark_label)
        ax.set_title(name, fontsize=10)
        ax.set_xticks(list(x))
        ax.grid(alpha=0.3)
    for ax in axes.flat[len(panels):]:
        ax.axis("off")
    for ax in axes[:, 0]:
        ax.set_ylabel(ylabel)
    for ax in axes[-1, :]:
        ax.set_xlabel(xlabel)
    if title:
        fig.suptitle(title, fontsize=11)
    fig.tight_layout()
    if marked:
        fig.legend(handles=marked, loc="upper left", bbox_to_anchor=(0.0, 0.0), frameon=False, fontsize=8.5)
        fig.text(0.01, -0.09, caption or "", ha="left", va="top", fontsize=8.5, wrap=True)
    else:
        _caption(fig, caption)
    _save(fig, path)
    return fig


def segmentation_rows(
    rows: Sequence[tuple],
    path,
    title: str | None = None,
    caption: str | None = None,
    camera="iso",
    window_size: tuple[int, int] = (450, 450),
):
    """Several meshes, one row each: ``rows`` are ``(mesh, label_names, views)``, views ``[(title, labels), ...]``.

    E.g. ground truth beside a prediction for meshes of different categories
    (the paper's Figs. 5-8); each row has its own legend, since the labels
    differ from category to category. A PNG at ``path``.
    """
    if not rows:
        raise ValueError("no rows to draw")
    ncols = max(len(views) for _, _, views in rows)
    height = 2.75 * len(rows) + 0.5
    fig = plt.figure(figsize=(2.6 * ncols + 1.6, height))
    # the images fill the rows: no figure margin but a strip for the title on top
    grid = fig.add_gridspec(len(rows), ncols + 1, width_ratios=[1.0] * ncols + [0.62], wspace=0.02, hspace=0.12,
                            left=0.0, right=1.0, bottom=0.0, top=1.0 - 0.5 / height)
    for r, (mesh, label_names, views) in enumerate(rows):
        for c, (text, labels) in enumerate(views):
            ax = fig.add_subplot(grid[r, c])
            ax.imshow(render(mesh, labels=labels, n_classes=len(label_names), camera=camera, window_size=window_size))
            ax.set_title(text, fontsize=9)
            ax.axis("off")
        host = fig.add_subplot(grid[r, ncols])
        host.axis("off")
        host.legend(handles=legend_handles(label_names), loc="center left", frameon=False, fontsize=8)
    if title:
        fig.suptitle(title, fontsize=12, y=1.0 - 0.05 / height, va="top")
    _caption(fig, caption)
    _save(fig, path)
    return fig
