"""`anseg segment` end to end on one mesh at several sizes: seconds by stage, per face, and the peak memory.

    python benchmarks/scale.py [--mesh FILE | --psb Teddy/162] [--subdivide 0 2 3] [--model psb/Teddy] [--repeat 1]
                               [--reference REV] [--json FILE]

The mesh (default: PSB Teddy/162, 20,188 faces, from ``$ANSEG_DATA``; without
data a synthetic figure subdivided to about 25K faces, ``segment.pick_mesh``)
is split in four each of ``--subdivide`` times (0, 2, 3: about 20K, 320K and
1.3M faces) and written to an OFF file, untimed. Each size is then segmented
by ``anseg segment --model MODEL FILE --quiet`` in a fresh process with an
empty anseg cache (``$ANSEG_CACHE`` a new folder: no features or eigenbasis
kept from before), as a user's first run would; the wall time is the
child's from start to exit (imports, reading, writing and all), and the peak
is its maximum resident set. Stages are timed by wrapping the package
functions behind them, a call inside another's counted in the outer one
only (``stage_timers(outermost=True)``); "other" is the rest of the wall
time: Python's start, imports, loading the model, the checks. With
``--repeat`` the fastest of that many runs is kept per size. ``--reference
REV`` runs the code of that git revision beside ours (a temporary
worktree), size by size, with the ratio of its time over ours.
"""

from __future__ import annotations

# first: importing stages pins the float kernels (anseg/kernels.py) before NumPy and torch load
from stages import import_from, parse_or_measure, reference_checkout, stage_timers

# isort: split
import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path


def scale_stages() -> dict:
    """Stage name: the package function behind it, as (owner, attribute); those the code at hand lacks are left out."""
    from segment import segment_stages

    import anseg.cache as cache
    import anseg.mesh_files as mesh_files
    import anseg.pipeline as pipeline

    stages = {
        "read mesh file": (mesh_files, "load_shapes"),
        "collapse to network size": (pipeline, "network_mesh"),
        "features (level 0)": (pipeline.features, "compute_groups"),
        **segment_stages(),
        "carry back to input": (pipeline.collapse, "upsample"),
        "write outputs": (cache, "atomic_write_all"),
    }
    return {stage: (owner, name) for stage, (owner, name) in stages.items() if hasattr(owner, name)}


def measure(args) -> None:
    """Runs in a child process: `anseg segment` on one file under the stage timers, its figures as one JSON line."""
    import_from(args.code)
    from anseg.cli import main

    totals = defaultdict(float)
    with tempfile.TemporaryDirectory() as out, stage_timers(totals, scale_stages(), outermost=True):
        status = main(["segment", "--model", args.model, args.mesh, "-o", str(Path(out) / "labels.ply"), "--quiet"])
    if status:
        raise SystemExit(f"anseg segment failed with status {status}")
    print(json.dumps({"stages": totals, "peak": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20}))


def run_child(mesh_file: Path, faces: int, model: str, code: str | None) -> dict:
    """One cold run in a fresh process and an empty cache: its stages, wall seconds and peak GiB."""
    with tempfile.TemporaryDirectory() as cache:
        started = time.perf_counter()
        done = subprocess.run([sys.executable, __file__, "--child", f"--model={model}", f"--mesh={mesh_file}",
                               *(["--code", code] if code else [])], env={**os.environ, "ANSEG_CACHE": cache},
                              check=True, capture_output=True, text=True)
        wall = time.perf_counter() - started
    figures = json.loads(done.stdout.strip().splitlines()[-1])
    figures["stages"]["other"] = wall - sum(figures["stages"].values())
    figures["stages"]["total"] = wall
    return {**figures, "faces": faces}


def print_table(sizes: list[int], runs: list[dict], reference: list[dict] | None) -> None:
    """Seconds by stage (rows) and size (columns), microseconds per face and the peak; cells "ours | reference"."""
    figures = {stage: lambda run, stage=stage: run["stages"].get(stage, 0.0) for stage in
               sorted(runs[-1]["stages"], key=lambda s: (s in ("other", "total"), s == "total", -runs[-1]["stages"][s]))}
    figures["microseconds per face"] = lambda run: 1e6 * run["stages"]["total"] / run["faces"]
    figures["peak resident GiB"] = lambda run: run["peak"]
    width = 13 if reference is None else 22
    print(f"{'stage':<26}" + "".join(f"{f'{n:,} faces':>{width}}" for n in sizes))
    for name, figure in figures.items():
        cells = [f"{figure(run):.2f}" + ("" if reference is None else f" | {figure(reference[i]):.2f}")
                 for i, run in enumerate(runs)]
        print(f"{name:<26}" + "".join(f"{cell:>{width}}" for cell in cells))
    for table, whose in [(runs, "ours"), *([(reference, "reference")] if reference is not None else [])]:
        if len(sizes) > 1:
            growth = figures["microseconds per face"](table[-1]) / figures["microseconds per face"](table[-2])
            print(f"time per face at {sizes[-1]:,} faces over that at {sizes[-2]:,} ({whose}): {growth:.2f}")


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--mesh", help="mesh file (default: the PSB test mesh --psb)")
    parser.add_argument("--psb", default="Teddy/162", help="PSB test mesh to start from (default: Teddy/162)")
    parser.add_argument("--subdivide", type=int, nargs="+", default=[0, 2, 3],
                        help="times each size splits every face in four (default: 0 2 3)")
    parser.add_argument("--model", default="psb/Teddy", help="model file or shipped model (default: psb/Teddy)")
    parser.add_argument("--repeat", type=int, default=1, help="runs per size, the fastest kept (default: 1)")
    parser.add_argument("--reference", help="git revision whose code segments the same files beside ours")
    args = parse_or_measure(parser, argv, measure)
    if args is None:  # a child: it measured
        return
    from segment import pick_mesh

    from anseg.mesh_files import save_mesh

    sizes, ours, theirs = [], [], []
    with tempfile.TemporaryDirectory() as folder, reference_checkout(args.reference) as code:
        for times in args.subdivide:
            mesh, name = pick_mesh(args.mesh, times, psb_name=args.psb)
            path = Path(folder) / f"mesh_x{times}.off"
            save_mesh(path, mesh)
            sizes.append(mesh.n_faces)
            load = os.getloadavg()[0]  # other work on the machine slows every figure: said beside them
            ours.append(min((run_child(path, mesh.n_faces, args.model, None) for _ in range(args.repeat)),
                            key=lambda r: r["stages"]["total"]))
            if code is not None:
                theirs.append(min((run_child(path, mesh.n_faces, args.model, code) for _ in range(args.repeat)),
                                  key=lambda r: r["stages"]["total"]))
            print(f"measured {name}: {mesh.n_faces:,} faces, {ours[-1]['stages']['total']:.1f} s"
                  + (f" ({args.reference}: {theirs[-1]['stages']['total']:.1f} s)" if code else "")
                  + f"; load average {load:.2f} before, {os.getloadavg()[0]:.2f} after", flush=True)
    print(f"anseg segment --model {args.model}, cold cache, fresh process per run, fastest of {args.repeat}"
          + (f"; cells: ours | {args.reference}" if args.reference else ""))
    print_table(sizes, ours, theirs if args.reference else None)
    if args.json:
        from anseg.study.store import environment

        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps({"settings": {k: v for k, v in vars(args).items() if k not in ("child", "code")},
                                         "faces": sizes, "ours": ours, "reference": theirs or None,
                                         "environment": environment()}, indent=1, default=str) + "\n")


if __name__ == "__main__":
    main()
