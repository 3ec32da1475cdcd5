"""Size of the page `anseg segment --html` writes (:func:`anseg.viewer.write_html`), on PSB meshes of three sizes, and
how much of a browser window its first view fills.

    ANSEG_DATA=/work/shared/datasets python benchmarks/page_size.py [--out FOLDER] [--mesh Category/id:SUBDIVISIONS ...]

Each mesh is a PSB mesh, split into four faces per face ``SUBDIVISIONS``
times (libigl's ``upsample``), segmented with the shipped model of its
category (``psb/<Category>``); the page is written as the command line
writes it (every level's attention filled). The defaults: Glasses/58 as it
is (3,710 faces), Bird/249 once (29,696) and Bird/258 twice (286,208).
Prints the faces, the page's size, the seconds ``write_html`` took and, where
Chromium is installed, the share of a 1400 x 900 window that the mesh of the
page's first view (the labels on the input mesh) covers: headless Chromium's
screenshot of the page, the pixels right of the page's column that are not
its white background. The pages stay in ``--out`` (default: a temporary
folder, removed).
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import tempfile
import time
from pathlib import Path

DEFAULT_MESHES = ("Glasses/58:0", "Bird/249:1", "Bird/258:2")
WINDOW = (1400, 900)
CHROMIUM = next(filter(None, map(shutil.which, ("chromium", "chromium-browser", "google-chrome"))), None)


def psb_mesh(spec: str):
    """The mesh ``Category/id:subdivisions`` names, and its category."""
    import igl

    from anseg import datasets
    from anseg.mesh import Mesh

    name, subdivisions = spec.split(":")
    category = name.split("/")[0]
    item = next(m for m in datasets.load("psb", category=category, split="all", progress=False) if m.name == name)
    mesh = item.mesh
    if int(subdivisions):
        mesh = Mesh(*igl.upsample(mesh.vertices, mesh.faces, int(subdivisions)))
    return mesh, category


def window_share(page: Path) -> float:
    """The share of a :data:`WINDOW` window, right of the page's column, that is not white in the page's screenshot."""
    import numpy as np
    from PIL import Image

    from anseg.viewer import COLUMN_REM

    picture = page.with_suffix(".png")
    subprocess.run([CHROMIUM, "--headless=new", "--no-sandbox", "--use-gl=swiftshader", "--enable-unsafe-swiftshader",
                    "--virtual-time-budget=20000", f"--window-size={WINDOW[0]},{WINDOW[1]}", f"--screenshot={picture}",
                    page.as_uri()], capture_output=True, timeout=300, check=True)
    pixels = np.asarray(Image.open(picture).convert("RGB")).astype(int)
    view = pixels[:, COLUMN_REM * 16:]  # a rem is 16 pixels at the browser's default font size
    return float(((255 - view).sum(axis=2) > 30).sum() / (WINDOW[0] * WINDOW[1]))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--mesh", nargs="+", default=DEFAULT_MESHES, metavar="CATEGORY/ID:SUBDIVISIONS")
    parser.add_argument("--out", type=Path, help="keep the pages in this folder")
    args = parser.parse_args()

    from anseg.pipeline import Segmenter, fill_attention, segment
    from anseg.viewer import write_html

    with tempfile.TemporaryDirectory() as scratch:
        folder = args.out or Path(scratch)
        folder.mkdir(parents=True, exist_ok=True)
        print(f"{'mesh':<22} {'faces':>8} {'page MB':>8} {'write s':>8} {'view %':>7}")
        for spec in args.mesh:
            mesh, category = psb_mesh(spec)
            model = Segmenter.pretrained(f"psb/{category}")
            result = segment(mesh, model)
            fill_attention(model, result.levels)
            path = folder / f"{spec.replace('/', '_').replace(':', '_x')}.html"
            start = time.perf_counter()
            write_html(result, model.label_names, path, title=spec)
            seconds = time.perf_counter() - start
            share = f"{100 * window_share(path):7.1f}" if CHROMIUM else f"{'-':>7}"
            print(f"{spec:<22} {mesh.n_faces:>8} {path.stat().st_size / 1e6:>8.2f} {seconds:>8.1f} {share}", flush=True)


if __name__ == "__main__":
    main()
