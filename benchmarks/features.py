"""Seconds per feature group and peak memory, 5K to 500K faces, beside a reference revision of the code.

    python benchmarks/features.py [--data ROOT] [--repeats 1] [--reference REV] [--reference-max 100000] [--studies]

The meshes: the PSB meshes (``LabeledDB_new`` under ROOT, else under
``$ANSEG_DATA``; an archive there is extracted once into the anseg cache)
whose face counts are nearest 5K, 10K and 25K, and ``igl.upsample`` copies
of PSB meshes (each face split in four, once or twice) for 50K to 500K.

Each mesh runs in a fresh process, so that its peak memory is its own:
``peak`` is that process's ``ru_maxrss`` (resident set size, everything
including C++ allocations) and ``+mem`` its growth over the resident size
just before the features were computed (imports done, mesh loaded, a small
warm-up mesh computed). Times are wall-clock seconds, the best of
``--repeats`` runs, each group timed alone through the public
``compute_groups`` (so each includes its share of the common preparation:
the unit-area copy, and the edge table for gc; ``smooth`` alone includes its
inputs sdf, gc and agd); ``default`` is ``compute`` of every group
``SegmentConfig`` uses by default, with the cache off.

The same meshes up to ``--reference-max`` faces are also measured with the
code of ``--reference`` (a git revision, checked out into a temporary
worktree), and each figure is printed beside it as a ratio (reference time
over ours: above 1 is a speed-up), so a change reads as a ratio measured in
one run, not as two noisy absolute times. The last table fits, per group,
the slope of log seconds against log faces (the scaling exponent) over the
meshes of at least 25K faces. ``--studies`` adds the accuracy-vs-cost tables
that chose the AGD source count and the SDF ray count.
"""

from __future__ import annotations

# first: importing stages pins the float kernels (anseg/kernels.py) before NumPy and torch load
from stages import import_from, reference_checkout

# isort: split
import argparse
import multiprocessing
import resource
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

TIMED_GROUPS = ("edge", "angles", "ratios", "gc", "sdf", "agd", "smooth", "hks")
# (target faces of the PSB mesh, times it is split in four): 5K .. 500K faces
PLAN = [(5_000, 0), (10_000, 0), (25_000, 0), (12_500, 1), (25_000, 1), (12_500, 2), (19_000, 2), (31_000, 2)]


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


def measure(path: str, upsample: int, repeats: int, code: str | None = None) -> dict:
    """Runs in a fresh process: time every group on one mesh, then the peak memory of the default set.

    ``code``: a checkout whose ``anseg`` is imported instead of this one's.
    """
    import_from(code)
    import igl
    import trimesh

    from anseg import features, load_mesh
    from anseg.mesh import Mesh
    from anseg.pipeline import SegmentConfig

    groups = SegmentConfig().groups
    warm = trimesh.creation.icosphere(subdivisions=2)
    features.compute(Mesh(warm.vertices, warm.faces), features.GROUPS, cache=False)  # imports, first calls
    mesh = load_mesh(path)
    for _ in range(upsample):
        vertices, faces = igl.upsample(mesh.vertices, mesh.faces)
        mesh = Mesh(vertices, faces)
    mesh.validate()
    before = rss_mib()
    default = best_time(lambda: features.compute(mesh, groups, cache=False), repeats)
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    row = {"faces": mesh.n_faces, "default": default, "peak": peak, "grown": peak - before}
    for group in TIMED_GROUPS:  # a reference revision may not know every group: nan there
        row[group] = best_time(lambda: features.compute_groups(mesh, [group]), repeats) if group in features.GROUPS else np.nan
    return row


def run_fresh(path: Path, upsample: int, repeats: int, code: str | None = None) -> dict:
    with ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn")) as pool:
        return pool.submit(measure, str(path), upsample, repeats, code).result()


def table(rows: list[tuple[str, dict, dict | None]]) -> str:
    """One line a mesh: each figure, and beside it the reference's time over ours where there is one."""
    columns = [*TIMED_GROUPS, "default"]
    heads = ["mesh", "faces", *columns, "peak MiB", "+mem MiB"]
    lines = []
    for name, row, reference in rows:
        cells = [name, f"{row['faces']:,}"]
        for c in columns:
            ratio = f" ({reference[c] / row[c]:.1f}x)" if reference else ""
            cells.append(f"{row[c]:.3f}{ratio}")
        peak_ratio = f" ({reference['peak'] / row['peak']:.2f}x)" if reference else ""
        cells += [f"{row['peak']:.0f}{peak_ratio}", f"{row['grown']:.0f}"]
        lines.append(cells)
    widths = [max(len(h), *(len(line[i]) for line in lines)) for i, h in enumerate(heads)]
    fmt = "  ".join(f"{{:<{w}}}" if i == 0 else f"{{:>{w}}}" for i, w in enumerate(widths))
    return "\n".join([fmt.format(*heads), fmt.format(*("-" * w for w in widths)), *(fmt.format(*line) for line in lines)])


def exponents(rows: list[tuple[str, dict, dict | None]], smallest: int = 25_000) -> str:
    """The slope of log seconds on log faces for every group, over the meshes of at least ``smallest`` faces."""
    chosen = [row for _, row, _ in rows if row["faces"] >= smallest]
    faces = np.log([row["faces"] for row in chosen])
    lines = [f"scaling exponent (slope of log seconds on log faces, {len(chosen)} meshes of {smallest:,} faces or more)"]
    for c in (*TIMED_GROUPS, "default", "peak"):
        slope = np.polyfit(faces, np.log([max(row[c], 1e-6) for row in chosen]), 1)[0]
        lines.append(f"  {c:<8} {slope:5.2f}")
    return "\n".join(lines)


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
        print(f"{n:>8} {seconds:>8.3f} {np.median(rel):>15.4f} {np.percentile(rel, 90):>12.4f} "
              f"{np.corrcoef(sdf, reference)[0, 1]:>12.4f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--data", help="folder holding LabeledDB_new/ or psb_labeled.tar.gz (default: $ANSEG_DATA)")
    parser.add_argument("--repeats", type=int, default=1, help="runs per measurement; the best is printed (default: 1)")
    parser.add_argument("--reference", help="git revision whose code is measured beside this one (default: none)")
    parser.add_argument("--reference-max", type=int, default=100_000,
                        help="measure the reference on meshes up to this many faces (default: 100000)")
    parser.add_argument("--studies", action="store_true", help="also print the AGD-sources and SDF-rays accuracy studies")
    args = parser.parse_args()

    folder = psb_folder(args.data)
    files = {p: face_count(p) for p in sorted(folder.glob("*/*.off"))}
    rows = []
    with reference_checkout(args.reference) as code:
        for target, upsample in PLAN:
            path = nearest(files, target)
            row = run_fresh(path, upsample, args.repeats)
            reference = run_fresh(path, upsample, args.repeats, code) if code and row["faces"] <= args.reference_max else None
            name = f"{path.parent.name}/{path.stem}" + (f" x{4 ** upsample}" if upsample else "")
            rows.append((name, row, reference))
            print(f"measured {name}: {row['faces']:,} faces, default {row['default']:.2f} s"
                  + (f" (reference {reference['default']:.2f} s)" if reference else ""), flush=True)
    print(f"\nseconds per group (best of {args.repeats}; each group alone), peak = ru_maxrss of a fresh process"
          + (f"; in brackets: {args.reference}'s time (peak) over ours, meshes up to {args.reference_max:,} faces"
             if args.reference else ""))
    print(table(rows))
    print(exponents(rows))
    if args.studies:
        studies(nearest(files, 25_000))


if __name__ == "__main__":
    main()
