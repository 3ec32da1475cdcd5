"""Seconds per feature group and peak memory, for meshes from 5K to 100K faces.

    python benchmarks/features.py [--data ROOT] [--repeats 3] [--studies]

The meshes: the PSB meshes (``LabeledDB_new`` under ROOT, else under
``$ANSEG_DATA``; an archive there is extracted once into the anseg cache)
whose face counts are nearest 5K, 10K and 25K, and ``igl.upsample`` copies
(each face split in four) of the 12.5K and 25K ones for 50K and 100K.

Each mesh runs in a fresh process, so that its peak memory is its own:
``peak`` is that process's ``ru_maxrss`` (resident set size, everything
including C++ allocations) and ``+mem`` its growth over the resident size
just before the features were computed (imports done, mesh loaded, a small
warm-up mesh computed). Times are wall-clock seconds, the best of
``--repeats`` runs, each group timed alone through the public
``compute_groups`` (so each includes its share of the common preparation:
the unit-area copy, and the edge table for gc); ``default``
is ``compute`` of DEFAULT_GROUPS with the cache off, the figure the 2 s
target is about; ``+smooth`` what adding the optional ``smooth`` group to
them costs on top (its inputs, sdf, gc and agd, are shared). ``--studies`` adds the
accuracy-vs-cost tables that chose the AGD source count and the SDF ray count.
"""

from __future__ import annotations

import argparse
import multiprocessing
import resource
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

TIMED_GROUPS = ("edge", "angles", "ratios", "gc", "sdf", "agd")


def psb_folder(data: str | None) -> Path:
    from anseg.datasets.archive import data_root, dataset_folder

    return dataset_folder(data_root(data), "LabeledDB_new", "psb_labeled.tar.gz")


def face_count(path: Path) -> int:
    """Faces in an OFF file, from its header (handles 'OFF' alone or with the counts on its line)."""
    with open(path) as handle:
        tokens = []
        for line in handle:
            tokens += line.split("#")[0].split()
            if len(tokens) >= 3:
                break
    counts = tokens[1:] if tokens[0].upper() == "OFF" else tokens
    return int(counts[1])


def nearest(files: dict[Path, int], target: int) -> Path:
    return min(files, key=lambda p: (abs(files[p] - target), str(p)))


def rss_mib() -> float:
    with open("/proc/self/statm") as handle:
        return int(handle.read().split()[1]) * resource.getpagesize() / 2**20


def best_time(fn, repeats: int) -> float:
    best = np.inf
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - start)
    return best


def measure(path: str, upsample: int, repeats: int) -> dict:
    """Runs in a fresh process: time every group on one mesh, then the peak memory of the default set."""
    import igl
    import trimesh

    from anseg import features, load_mesh
    from anseg.mesh import Mesh

    warm = trimesh.creation.icosphere(subdivisions=2)
    features.compute(Mesh(warm.vertices, warm.faces), features.GROUPS, cache=False)  # imports, first calls
    mesh = load_mesh(path)
    for _ in range(upsample):
        vertices, faces = igl.upsample(mesh.vertices, mesh.faces)
        mesh = Mesh(vertices, faces)
    mesh.validate()
    before = rss_mib()
    default = best_time(lambda: features.compute(mesh, cache=False), repeats)
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    row = {"faces": mesh.n_faces, "default": default, "peak": peak, "grown": peak - before}
    for group in TIMED_GROUPS:
        row[group] = best_time(lambda: features.compute_groups(mesh, [group]), repeats)
    with_smooth = best_time(lambda: features.compute(mesh, (*features.DEFAULT_GROUPS, "smooth"), cache=False), repeats)
    row["+smooth"] = with_smooth - default
    return row


def table(rows: list[tuple[str, dict]]) -> str:
    columns = ["faces", *TIMED_GROUPS, "default", "+smooth", "peak", "grown"]
    heads = ["mesh", "faces", *TIMED_GROUPS, "default", "+smooth", "peak MiB", "+mem MiB"]
    lines = []
    for name, row in rows:
        cells = [name, f"{row['faces']:,}"]
        cells += [f"{row[c]:.3f}" for c in columns[1:-2]]
        cells += [f"{row['peak']:.0f}", f"{row['grown']:.0f}"]
        lines.append(cells)
    widths = [max(len(h), *(len(line[i]) for line in lines)) for i, h in enumerate(heads)]
    fmt = "  ".join(f"{{:<{w}}}" if i == 0 else f"{{:>{w}}}" for i, w in enumerate(widths))
    return "\n".join([fmt.format(*heads), fmt.format(*("-" * w for w in widths)), *(fmt.format(*line) for line in lines)])


def studies(path: Path) -> None:
    """Accuracy against a dense reference, and cost, of the AGD source count and the SDF ray count."""
    from anseg import features, load_mesh

    mesh = load_mesh(path)
    print(f"\nAGD sources on {path.parent.name}/{path.name} ({mesh.n_faces:,} faces); reference: 1024 sources")
    reference = features.compute_groups(mesh, ["agd"], agd_sources=1024)["agd"]
    print(f"{'sources':>8} {'seconds':>8} {'mean rel err':>13} {'max rel err':>12} {'agd_rel max abs err':>20}")
    for n in (16, 32, 64, 128, 256):
        start = time.perf_counter()
        agd = features.compute_groups(mesh, ["agd"], agd_sources=n)["agd"]
        seconds = time.perf_counter() - start
        rel = np.abs(agd[:, 0] - reference[:, 0]) / reference[:, 0]
        print(f"{n:>8} {seconds:>8.3f} {rel.mean():>13.4f} {rel.max():>12.4f} {np.abs(agd[:, 1] - reference[:, 1]).max():>20.4f}")
    print("\nSDF rays per face on the same mesh; reference: 128 rays")
    reference = features.compute_groups(mesh, ["sdf"], sdf_rays=128)["sdf"][:, 0]
    print(f"{'rays':>8} {'seconds':>8} {'median rel err':>15} {'p90 rel err':>12} {'correlation':>12}")
    for n in (8, 16, 24, 32):
        start = time.perf_counter()
        sdf = features.compute_groups(mesh, ["sdf"], sdf_rays=n)["sdf"][:, 0]
        seconds = time.perf_counter() - start
        rel = np.abs(sdf - reference) / reference
        print(f"{n:>8} {seconds:>8.3f} {np.median(rel):>15.4f} {np.percentile(rel, 90):>12.4f} {np.corrcoef(sdf, reference)[0, 1]:>12.4f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--data", help="folder holding LabeledDB_new/ or psb_labeled.tar.gz (default: $ANSEG_DATA)")
    parser.add_argument("--repeats", type=int, default=3, help="runs per measurement; the best is printed")
    parser.add_argument("--studies", action="store_true", help="also print the AGD-sources and SDF-rays accuracy studies")
    args = parser.parse_args()

    folder = psb_folder(args.data)
    files = {p: face_count(p) for p in sorted(folder.glob("*/*.off"))}
    plan = [(nearest(files, n), 0) for n in (5_000, 10_000, 25_000)]
    plan += [(nearest(files, 12_500), 1), (nearest(files, 25_000), 1)]
    rows = []
    context = multiprocessing.get_context("spawn")
    for path, upsample in plan:
        with ProcessPoolExecutor(1, mp_context=context) as pool:
            row = pool.submit(measure, str(path), upsample, args.repeats).result()
        name = f"{path.parent.name}/{path.stem}" + (" x4" if upsample else "")
        rows.append((name, row))
        print(f"measured {name}: {row['faces']:,} faces, {row['default']:.2f} s", flush=True)
    print(f"\nseconds per group (best of {args.repeats}; each group alone), peak = ru_maxrss of a fresh process")
    print(table(rows))
    if args.studies:
        studies(nearest(files, 25_000))


if __name__ == "__main__":
    main()
