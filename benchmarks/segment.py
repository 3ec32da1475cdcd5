"""End-to-end segmentation time by stage, and peak memory, on one mesh.

    python benchmarks/segment.py [--mesh FILE | --near FACES] [--model MODEL.pt | --config NAME] [--subdivide N]
                                 [--repeat 3] [--reference REV] [--set OVERRIDES] [--reference-set OVERRIDES]
                                 [--json FILE]

Without ``--mesh`` it takes the PSB test mesh closest to ``--near`` faces (25K) from
``$ANSEG_DATA`` (or a synthetic shape subdivided to about that size when no data is there);
``--subdivide 1`` splits every face in four first (a 25K mesh becomes 100K,
twice gives 400K; ``--near 19000 --subdivide 2`` gives about 300K). Without
``--model`` (a file, or a shipped model's name as ``anseg models`` lists
it) a model of the named configuration ``--config`` (default: ``default``;
``v1`` is the network before validation) is trained for one epoch on three
synthetic shapes: speed does not depend on what the weights learnt;
``--set`` gives it other settings (the field=value syntax of
``anseg.configs``), and ``--reference-set`` the reference its own (``""``:
the defaults; with our code where there is no ``--reference``). Features,
and the eigenbasis of a model that reads one, are computed without the
cache, so their cost is in the figures. Stages are timed by
wrapping the package functions that implement them; peak memory is the
process's peak resident set (ru_maxrss) measured in a fresh child process
per mesh, minus the resident set after imports and loading. With
``--reference`` a second child runs the code of that git revision (a
temporary worktree) on the same mesh, and every stage is printed beside it
with the reference's time over ours. Without ``--model`` each child trains
its own one-epoch model, so the two codes segment with different weights
(speed does not depend on them). ``--json FILE`` keeps the figures with the
machine, the versions and the code revision (``results/benchmarks/`` holds
the run the claims ledger quotes for the paper's cost claim).
"""

from __future__ import annotations

# first: importing stages pins the float kernels (anseg/kernels.py) before NumPy and torch load
from stages import import_from, kernels_of_children, parse_or_measure, print_stages, reference_checkout, stage_timers

# isort: split
import argparse
import dataclasses
import json
import resource
import subprocess
import sys
import time
from collections import defaultdict
from functools import partial
from pathlib import Path

import numpy as np


def pick_mesh(path: str | None, subdivide: int, near: int = 25_000, psb_name: str | None = None):
    """The mesh file at ``path``; else the PSB test mesh named ``psb_name`` (e.g. ``Teddy/162``) or the one of Teddy,
    Human and Airplane closest to ``near`` faces; else, without data, a synthetic figure split in four as often as
    brings it closest to ``near`` faces. Then split in four ``subdivide`` times. Returns the mesh and its name."""
    import igl

    from anseg import datasets, load_mesh
    from anseg.mesh import Mesh

    if path:
        mesh, name = load_mesh(path), path
    else:
        try:
            categories = [psb_name.split("/")[0]] if psb_name else ["Teddy", "Human", "Airplane"]
            items = [m for c in categories for m in datasets.load("psb", category=c, split="test", progress=False)]
            item = (next(m for m in items if m.name == psb_name) if psb_name
                    else min(items, key=lambda m: abs(m.mesh.n_faces - near)))
            mesh, name = item.mesh, f"PSB {item.name}"
        except datasets.DatasetError:
            item = datasets.load("synthetic", category="figure", split="test", progress=False)[0]
            times = max(0, round(np.log(near / item.mesh.n_faces) / np.log(4)))
            v, f = igl.upsample(item.mesh.vertices, item.mesh.faces, times)
            mesh, name = Mesh(v, f), f"synthetic {item.name} subdivided x{times}"
    if subdivide:
        v, f = igl.upsample(mesh.vertices, mesh.faces, subdivide)
        mesh, name = Mesh(v, f), f"{name} subdivided x{subdivide}"
    return mesh, name


def quick_model(name: str, overrides: str = ""):
    from anseg import datasets
    from anseg.configs import configuration
    from anseg.train import fit

    segment, train = configuration(name, ",".join(filter(None, ["train.epochs=1", overrides])))
    shapes = datasets.load("synthetic", category="figure", split="train", progress=False)[:3]
    return fit(shapes, shapes[0].label_names, segment, train, progress=False)


def segment_stages() -> dict:
    """Stage name: the package function behind it, as (owner, attribute)."""
    import anseg.hierarchy as hierarchy
    import anseg.pipeline as pipeline

    return {
        "cluster + sequence": (pipeline, "layout"),
        "collapse": (pipeline.collapse, "downsample"),
        "coarse features": (pipeline, "coarse_groups"),
        "upsample": (hierarchy, "upsample_through"),
        "graph cut": (pipeline, "graph_cut"),
        "network": (pipeline.Segmenter, "__call__"),
        "spectrum": (pipeline.spectral, "face_spectrum"),
    }


def measure(args) -> None:
    """Runs in a child process: time the stages and the peak memory, printed as one JSON line."""
    import_from(args.code)
    import torch

    from anseg.features import compute_groups
    from anseg.pipeline import Segmenter, segment

    if args.threads:
        torch.set_num_threads(args.threads)
    import anseg.pipeline as pipeline

    # a new mesh pays for its eigenbasis: no disk cache (the HKS features' solve is shared in memory, as in use)
    pipeline.spectral.face_spectrum = partial(pipeline.spectral.face_spectrum, cache=False)
    if not args.model:
        model = quick_model(args.config, args.set)
    else:
        model = Segmenter.load(args.model) if Path(args.model).is_file() else Segmenter.pretrained(args.model)
    mesh, name = pick_mesh(args.mesh, args.subdivide, args.near)
    baseline = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    # segment's own first step where the model segments in the canonical pose: the features are then the canonical mesh's
    canonical = getattr(model.config, "canonical", False)
    config = dataclasses.replace(model.config, canonical=False) if canonical else model.config

    def posed(mesh):
        from anseg.cluster import canonical_mesh

        return canonical_mesh(mesh)[0] if canonical else mesh

    warm = posed(mesh)
    segment(warm, model, config, groups=compute_groups(warm, config.groups, cache=False))  # numba and torch first calls
    runs = []
    for _ in range(args.repeat):
        totals = defaultdict(float)
        start = time.perf_counter()
        target = posed(mesh)
        if canonical:
            totals["canonical pose"] = time.perf_counter() - start
        started = time.perf_counter()
        groups = compute_groups(target, config.groups, cache=False)
        totals["features (level 0)"] = time.perf_counter() - started
        with stage_timers(totals, segment_stages()):
            segment(target, model, config, groups=groups)
        totals["total"] = time.perf_counter() - start
        runs.append(totals)
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    best = min(runs, key=lambda t: t["total"])
    what = (f"mesh: {name}, {mesh.n_faces} faces; config: {model.config.cycles} cycles at ratio {model.config.ratio}, "
            f"mode {model.config.mode}\ntorch threads: {torch.get_num_threads()}; best of {args.repeat} runs after a warm-up")
    from anseg.kernels import in_force

    print(json.dumps({"what": what, "mesh": name, "faces": mesh.n_faces, "stages": best, "peak": peak / 2**20,
                      "baseline": baseline / 2**20, "kernels": in_force()}))


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--mesh", help="mesh file (default: a PSB test mesh near 25K faces)")
    parser.add_argument("--model", help="model file written by `anseg train` (default: a one-epoch synthetic model)")
    parser.add_argument("--near", type=int, default=25_000,
                        help="without --mesh, the PSB test mesh closest to this many faces (default: 25000)")
    parser.add_argument("--subdivide", type=int, default=0, help="split every face in four this many times first")
    parser.add_argument("--config", default="default",
                        help="named configuration of the one-epoch model when no --model is given (default: default)")
    parser.add_argument("--repeat", type=int, default=3, help="timed runs (default: 3)")
    parser.add_argument("--threads", type=int, default=0, help="torch threads (default: torch's choice)")
    parser.add_argument("--reference", help="git revision whose code segments the same mesh beside this one")
    parser.add_argument("--set", default="", help="overrides of the one-epoch model's settings, field=value,... (default: none)")
    parser.add_argument("--reference-set", help="the reference run's overrides instead of --set (\"\": the defaults)")
    parser.add_argument("--reference-kernels", choices=["native"],
                        help="the reference runs each library's own kernels (ANSEG_KERNELS=native): the pin's cost")
    args = parse_or_measure(parser, argv, measure)
    if args is None:  # a child: it measured
        return
    own = [f"--subdivide={args.subdivide}", f"--near={args.near}", f"--repeat={args.repeat}", f"--threads={args.threads}",
           f"--config={args.config}",
           *([f"--mesh={args.mesh}"] if args.mesh else []), *([f"--model={args.model}"] if args.model else [])]
    reference_set = args.set if args.reference_set is None else args.reference_set

    def child(code: str | None, overrides: str, kernels: str | None = None) -> dict:  # a fresh process: the peak is this mesh's
        extra = ["--code", code] if code else []
        with kernels_of_children(kernels):
            done = subprocess.run([sys.executable, __file__, "--child", *own, f"--set={overrides}", *extra], check=True,
                                  capture_output=True, text=True)
        return json.loads(done.stdout.strip().splitlines()[-1])

    with reference_checkout(args.reference) as code:
        ours = child(None, args.set)
        compared = code is not None or args.reference_set is not None or args.reference_kernels is not None
        reference = child(code, reference_set, args.reference_kernels) if compared else None
    print(ours["what"] + (f"\nsettings: [{args.set or 'defaults'}]" if args.set or compared else ""))
    label = " ".join(filter(None, [args.reference, f"[{reference_set or 'defaults'}]" if args.reference_set is not None else "",
                                   f"{args.reference_kernels} kernels" if args.reference_kernels else ""]))
    print_stages(ours["stages"], reference["stages"] if reference else None, name=label or "reference")
    print(f"peak resident memory: {ours['peak']:.2f} GiB (after loading: {ours['baseline']:.2f} GiB)"
          + (f"; {label}: {reference['peak']:.2f} GiB" if reference else ""))
    if args.json:
        from anseg.study.store import environment

        settings = {k: v for k, v in vars(args).items() if k not in ("child", "code", "json")}
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps({"settings": settings, "ours": ours, "reference": reference,
                                         "environment": environment()}, indent=1, default=str) + "\n")


if __name__ == "__main__":
    np.seterr(all="ignore")
    main()
