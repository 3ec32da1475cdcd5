"""Speed of the collapse engine against libigl's C++ ``decimate`` for the same reduction.

Runs ``--cycles`` downsampling cycles at ``--ratio`` (default 4 x 0.5) on one
mesh, in ``nonuniform`` mode with random scores (the pipeline's path) and in
``uniform`` mode, then ``igl.decimate(V, F, max_m)`` (shortest edge, midpoint
placement: the same cost as our ``uniform``) in one go to the same final face
count. Times are the best of ``--repeats`` runs after a warm-up run (which
also loads numba's compiled cache). Also times carrying class probabilities
back through all levels (``upsample_through``).

Peak memory: each method runs once more in a fresh child process that first
does a warm-up on a small mesh (imports and JIT land in the baseline),
returns freed heap to the OS (glibc ``malloc_trim``), then resets the kernel's
resident-set high-water mark (``5 > /proc/self/clear_refs``,
Linux) and runs once; the figure is the high-water mark (``VmHWM``) minus the
resident set before the call (``VmRSS``): what the call itself adds, native
(numba, C++) allocations included.

Mesh: ``--mesh PATH``; else the PSB test mesh closest to 25K faces from
``$ANSEG_DATA`` (Teddy) when the data is there; else a subdivided icosphere.
"""

from __future__ import annotations

import anseg  # noqa: F401  first: importing anseg pins the float kernels before NumPy and torch load

# isort: split
import argparse
import ctypes
import gc
import json
import subprocess
import sys
import time

import numpy as np

from anseg.collapse import downsample
from anseg.hierarchy import upsample_through
from anseg.mesh import Mesh
from anseg.mesh_files import load_mesh

METHODS = ("nonuniform", "uniform", "igl")
TARGET_FACES = 25_000


def pick_mesh(path: str | None) -> tuple[Mesh, str]:
    """The mesh to time and a description of where it came from."""
    if path:
        return load_mesh(path), path
    try:
        from anseg import datasets

        items = datasets.load("psb", category="Teddy", split="test", progress=False)
        item = min(items, key=lambda i: abs(i.mesh.n_faces - TARGET_FACES))
        return item.mesh, f"PSB {item.name}"
    except Exception as exc:  # no data root, or the data set is unreadable: fall back to a synthetic mesh
        import trimesh

        sphere = trimesh.creation.icosphere(subdivisions=5)
        return Mesh(sphere.vertices, sphere.faces), f"icosphere, 5 subdivisions (no PSB data: {exc})"


def run_cycles(mesh: Mesh, mode: str, cycles: int, ratio: float, seed: int = 0):
    """``cycles`` downsampling cycles; random static scores in nonuniform mode."""
    rng = np.random.default_rng(seed)
    records = []
    for _ in range(cycles):
        scores = rng.random(mesh.n_faces) if mode == "nonuniform" else None
        mesh, record = downsample(mesh, scores, ratio=ratio, mode=mode)
        records.append(record)
    return mesh, records


def run_igl(mesh: Mesh, n_faces: int):
    import igl

    result = igl.decimate(np.asfortranarray(mesh.vertices), np.asfortranarray(mesh.faces.astype(np.int32)), n_faces)
    # libigl 2.6.3's binding returns (U, G, J, I); older ones put a success flag first
    return result[-3]


def best_time(call, repeats: int) -> float:
    call()  # warm-up: JIT cache load, first-touch allocations
    best = np.inf
    for _ in range(repeats):
        started = time.perf_counter()
        call()
        best = min(best, time.perf_counter() - started)
    return best


def measure_peak(method: str, mesh_path: str | None, cycles: int, ratio: float, final_faces: int) -> float:
    """Peak RSS growth in MiB of one call, in a fresh child process."""
    command = [sys.executable, __file__, "--probe", method, "--cycles", str(cycles), "--ratio", str(ratio),
               "--probe-faces", str(final_faces)]
    if mesh_path:
        command += ["--mesh", mesh_path]
    out = subprocess.run(command, check=True, capture_output=True, text=True).stdout
    return json.loads(out.strip().splitlines()[-1])["peak_growth_mib"]


def probe(args) -> None:
    """Child process: warm up on a small mesh, then report the peak RSS growth of one call."""
    import trimesh

    mesh, _ = pick_mesh(args.mesh)
    small = trimesh.creation.icosphere(subdivisions=3)
    small = Mesh(small.vertices, small.faces)
    call = {
        "nonuniform": lambda m: run_cycles(m, "nonuniform", args.cycles, args.ratio),
        "uniform": lambda m: run_cycles(m, "uniform", args.cycles, args.ratio),
        "igl": lambda m: run_igl(m, max(4, m.n_faces // 2 ** args.cycles) if m is small else args.probe_faces),
    }[args.probe]
    call(small)
    gc.collect()
    ctypes.CDLL("libc.so.6").malloc_trim(0)  # hand freed heap back to the OS so that the call's growth shows
    with open("/proc/self/clear_refs", "w") as handle:
        handle.write("5")  # reset the peak resident set to the current one
    before = _status_kib("VmRSS")
    call(mesh)
    print(json.dumps({"peak_growth_mib": (_status_kib("VmHWM") - before) / 1024}))


def _status_kib(field: str) -> int:
    with open("/proc/self/status") as handle:
        for line in handle:
            if line.startswith(field + ":"):
                return int(line.split()[1])
    raise RuntimeError(f"/proc/self/status has no {field}")


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--mesh", help="mesh file to time (default: a ~25K-face PSB mesh, else an icosphere)")
    parser.add_argument("--cycles", type=int, default=4)
    parser.add_argument("--ratio", type=float, default=0.5)
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--probe", choices=METHODS, help=argparse.SUPPRESS)
    parser.add_argument("--probe-faces", type=int, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.probe:
        probe(args)
        return

    mesh, source = pick_mesh(args.mesh)
    coarse, records = run_cycles(mesh, "nonuniform", args.cycles, args.ratio)
    final_faces = coarse.n_faces
    igl_faces = len(run_igl(mesh, final_faces))
    print(f"mesh: {source}: {mesh.n_faces} faces -> {final_faces} after {args.cycles} cycles at ratio {args.ratio}"
          f" (igl.decimate: {igl_faces})")

    times = {
        "nonuniform": best_time(lambda: run_cycles(mesh, "nonuniform", args.cycles, args.ratio), args.repeats),
        "uniform": best_time(lambda: run_cycles(mesh, "uniform", args.cycles, args.ratio), args.repeats),
        "igl": best_time(lambda: run_igl(mesh, final_faces), args.repeats),
    }
    probs = np.random.default_rng(0).random((final_faces, 8))
    upsample_seconds = best_time(lambda: upsample_through(records, probs), args.repeats)
    peaks = {m: measure_peak(m, args.mesh, args.cycles, args.ratio, final_faces) for m in METHODS}

    print(f"best of {args.repeats} after a warm-up; peak MiB = peak RSS growth of one call in a warmed-up child (VmHWM - VmRSS)")
    print(f"{'method':<34}{'ms':>9}{'x igl':>8}{'peak MiB':>10}")
    labels = {"nonuniform": f"anseg nonuniform, {args.cycles} cycles", "uniform": f"anseg uniform, {args.cycles} cycles",
              "igl": "igl.decimate, one call"}
    for method in METHODS:
        print(f"{labels[method]:<34}{1e3 * times[method]:>9.1f}{times[method] / times['igl']:>8.2f}{peaks[method]:>10.1f}")
    print(f"{'upsample_through, 8 classes':<34}{1e3 * upsample_seconds:>9.1f}")


if __name__ == "__main__":
    main()
