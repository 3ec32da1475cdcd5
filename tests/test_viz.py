"""viz: colours, offscreen renders and the PNG plots the notebooks write."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from conftest import grid_mesh  # noqa: E402

from anseg import viz  # noqa: E402


@pytest.fixture(scope="session")
def offscreen():
    """Skip the render tests, with the reason, only where VTK itself cannot render offscreen here.

    Checked once, with a plain pyvista scene and none of our code, so that a
    failure of our render functions fails the tests instead of skipping them.
    """
    pyvista = viz._pyvista()
    try:
        plotter = pyvista.Plotter(off_screen=True, window_size=[16, 16])
        plotter.add_mesh(pyvista.Sphere())
        plotter.screenshot(return_img=True)
        plotter.close()
    except Exception as exc:  # VTK reports a missing EGL/OSMesa in several ways
        pytest.skip(f"no offscreen OpenGL context here ({type(exc).__name__}: {exc})")


def _png_size(path) -> tuple[int, int]:
    image = plt.imread(path)
    return image.shape[1], image.shape[0]


def test_palette_gives_each_class_its_own_colour():
    for n in (3, 10, 14, 25):
        colours = viz.palette(n)
        assert colours.shape == (n, 3) and colours.dtype == np.uint8
        assert len({tuple(c) for c in colours}) == n


def test_label_colors_follow_the_labels():
    colours = viz.label_colors(np.array([0, 1, 1, 2]), 3)
    assert colours.shape == (4, 3)
    assert (colours[1] == colours[2]).all()
    assert not (colours[0] == colours[1]).all() and not (colours[1] == colours[3]).all()


def test_label_colors_refuse_labels_out_of_range():
    with pytest.raises(ValueError, match="outside"):
        viz.label_colors(np.array([0, 3]), 3)
    with pytest.raises(ValueError, match="integer"):
        viz.label_colors(np.array([0.5, 1.0]), 3)


def test_legend_handles_match_label_colors():
    handles = viz.legend_handles(["head", "torso", "arm"])
    assert [h.get_label() for h in handles] == ["head", "torso", "arm"]
    expected = viz.label_colors(np.array([1]), 3)[0] / 255.0
    assert np.allclose(handles[1].get_facecolor()[:3], expected)


def test_render_labels_shows_the_label_colours(offscreen):
    mesh = grid_mesh(4, closed=True)
    labels = (mesh.face_centroids[:, 2] > 0).astype(np.int64)
    image = viz.render(mesh, labels=labels, n_classes=2, window_size=(120, 100))
    assert image.shape == (100, 120, 3) and image.dtype == np.uint8
    background = np.all(image == 255, axis=-1)
    assert 0.05 < 1 - background.mean() < 0.95  # the mesh fills part of the frame, not none or all
    # shading darkens the palette colours, but both classes' hues must be there
    pixels = image[~background].astype(float)
    hues = pixels / np.maximum(pixels.sum(axis=1, keepdims=True), 1)
    for colour in viz.palette(2).astype(float):
        target = colour / colour.sum()
        assert (np.abs(hues - target).sum(axis=1) < 0.05).mean() > 0.05


def test_render_scalars_follow_the_colour_map(offscreen):
    mesh = grid_mesh(4, closed=True)
    values = mesh.face_centroids[:, 2]
    image = viz.render(mesh, face_scalars=values, cmap="Reds", camera="front", window_size=(80, 80))
    assert image.shape == (80, 80, 3)
    pixels = image[~np.all(image == 255, axis=-1)].astype(int)
    assert len(pixels) > 100
    assert (pixels[:, 0] >= pixels[:, 2]).mean() > 0.9  # reds: red channel dominates blue
    assert pixels.std(axis=0).max() > 10  # not one flat colour: the scalars vary


def test_render_refuses_mismatched_input(offscreen):
    mesh = grid_mesh(2)
    with pytest.raises(ValueError, match="not both"):
        viz.render(mesh, face_scalars=np.zeros(mesh.n_faces), labels=np.zeros(mesh.n_faces, dtype=int), n_classes=1)
    with pytest.raises(ValueError, match="n_classes"):
        viz.render(mesh, labels=np.zeros(mesh.n_faces, dtype=int))
    with pytest.raises(ValueError, match="face_scalars"):
        viz.render(mesh, face_scalars=np.zeros(mesh.n_faces + 1))
    with pytest.raises(ValueError, match="camera"):
        viz.render(mesh, camera="behind")


def test_render_panel_writes_a_png_with_legend_and_colour_bar(tmp_path):
    images = [np.full((40, 50, 3), 200, np.uint8), np.zeros((40, 50, 3), np.uint8)]
    path = tmp_path / "figures" / "panel.png"
    fig = viz.render_panel(images, ["a", "b"], path, legend=viz.legend_handles(["x", "y"]),
                           colorbar={"cmap": "Reds", "vmin": 0, "vmax": 2, "label": "attention"})
    plt.close(fig)
    assert path.is_file()
    width, height = _png_size(path)
    assert width > height > 0
    with pytest.raises(ValueError, match="title"):
        viz.render_panel(images, ["only one"], tmp_path / "bad.png")


def test_label_panel_renders_each_view(offscreen, tmp_path):
    mesh = grid_mesh(4, closed=True)
    truth = (mesh.face_centroids[:, 2] > 0).astype(np.int64)
    path = tmp_path / "labels.png"
    fig = viz.label_panel([(mesh, "truth", truth), (mesh, "prediction", 1 - truth)], ["top", "bottom"], path,
                          window_size=(60, 60))
    assert [ax.get_title() for ax in fig.axes[:2]] == ["truth", "prediction"]
    assert [t.get_text() for t in fig.legends[0].get_texts()] == ["top", "bottom"]
    plt.close(fig)
    assert path.is_file()


def test_line_panels_write_one_labelled_panel_per_entry_and_ring_the_marked_point(tmp_path):
    path = tmp_path / "fig11.png"
    mean = [0.8, 0.85, np.nan]
    panels = {"removing 0.3": (mean, [0.78, 0.83, np.nan], [0.82, 0.87, np.nan]),
              "removing 0.5": ([0.82, 0.9, 0.91], [0.8, 0.88, 0.9], [0.84, 0.92, 0.92])}
    fig = viz.line_panels([1, 2, 4], panels, path, xlabel="cycles N", ylabel="accuracy",
                          mark=("removing 0.5", 4), mark_label="the paper's choice")
    shown = [ax for ax in fig.axes if ax.get_title()]
    assert [ax.get_title() for ax in shown] == ["removing 0.3", "removing 0.5"]
    assert shown[0].get_xlabel() == "cycles N" and shown[0].get_ylabel() == "accuracy"
    assert [t.get_text() for t in fig.legends[0].get_texts()] == ["the paper's choice"]
    plt.close(fig)
    assert path.is_file() and min(_png_size(path)) > 100
    with pytest.raises(ValueError, match="one mean, low and high"):
        viz.line_panels([1, 2], {"r": ([0.1], [0.1], [0.1])}, tmp_path / "bad.png", xlabel="x", ylabel="y")


def test_bar_plot_writes_a_png_with_one_bar_per_group_and_series(tmp_path):
    path = tmp_path / "fig12.png"
    series = {"edge": [0.6, 0.7], "edge+gc": [0.65, 0.72], "edge+gc+sdf": [0.8, 0.81]}
    fig = viz.bar_plot(["Human", "Teddy"], series, path, xlabel="category", ylabel="accuracy", legend_title="features")
    ax = fig.axes[0]
    assert len(ax.patches) == 6
    assert ax.get_ylabel() == "accuracy" and [t.get_text() for t in ax.get_xticklabels()] == ["Human", "Teddy"]
    plt.close(fig)
    assert path.is_file()


def test_paper_beside_ours_draws_one_split_without_whiskers_and_missing_paper_rows(tmp_path):
    nan = float("nan")
    ours = {"nonuniform": {"A": 80.0, "B": 90.0}, "none": {"A": 75.0, "B": 85.0}}
    spread = {"nonuniform": {"A": nan, "B": nan}, "none": {"A": nan, "B": nan}}  # one split: no spread
    path = tmp_path / "plot.png"
    for paper in ({"nonuniform": {"A": 94.0, "B": 96.0}}, {}):  # the paper's numbers, or none (synthetic data)
        viz.paper_beside_ours(["A", "B"], ["nonuniform", "none"], ours, spread, paper, path, "accuracy (%)")
        assert path.stat().st_size > 0
    with pytest.raises(ValueError, match="no finite value"):
        viz.paper_beside_ours(["A"], ["none"], {"none": {"A": nan}}, {"none": {"A": nan}}, {}, path, "accuracy (%)")
