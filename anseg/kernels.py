"""One choice of float kernels on every x86-64 machine with AVX2, made before torch, NumPy and numba load.

Why: the math libraries choose their kernels by the CPU's vendor and
instruction set (torch's own vectorised loops by AVX2 or AVX-512, MKL by
vendor as well, NumPy and numba by every feature the CPU reports). Kernels
that round one last bit otherwise move the attention, the weighted collapse
turns that bit into another hierarchy, and whole regions change label. So,
unpinned, a number belongs to the CPU that made it.

The rule: importing :mod:`anseg` (the CLI, a notebook, a worker alike) sets
each variable of :data:`PIN` that the user has not set, so every library picks
the AVX2 kernels that every x86-64 machine of level v3 has. The variables are
read when each library loads (NumPy, numba) or first computes (torch, MKL,
oneDNN), so child processes inherit the choice. A library loaded earlier with
other kernels keeps them: :func:`pin` warns once, naming it.
OpenBLAS (NumPy's and SciPy's BLAS) is left to the machine; its own choice is
recorded (:func:`in_force`). ``ANSEG_KERNELS=native`` leaves every library
to its own choice: the runs stored before the pin were made that way.
"""

from __future__ import annotations

import os
import platform
import sys
import warnings
from pathlib import Path

#: The name of this pin in the records: a change to :data:`PIN` is a new name.
PIN_NAME = "avx2-1"
OPT_OUT = "ANSEG_KERNELS"

#: What each library is told, and why that variable.
PIN = {
    "ATEN_CPU_CAPABILITY": "avx2",  # torch's vectorised loops (softmax, layer norm, exp): AVX2, not AVX-512
    "MKL_CBWR": "AVX2,STRICT",  # MKL (torch's BLAS): the AVX2 code path whatever the vendor, the same for any thread count
    "MKL_ENABLE_INSTRUCTIONS": "AVX2",  # MKL's functions outside conditional reproducibility
    "ONEDNN_MAX_CPU_ISA": "AVX2",  # oneDNN (torch's mkldnn)
    "NUMBA_CPU_NAME": "haswell",  # numba compiles for the first AVX2 CPU ...
    "NUMBA_CPU_FEATURES": "",  # ... with that CPU's features, not the host's (numba's default with a name alone)
    # NumPy's SIMD loops (exp, log, sort) at the AVX2 level: its AVX-512 targets, as NumPy 2.4 names them (an older
    # NumPy ignores these names and keeps its AVX-512 loops; the record's "numpy" entry shows which ran)
    "NPY_DISABLE_CPU_FEATURES": "X86_V4 AVX512_ICL AVX512_SPR",
}

_warned: set[str] = set()


class KernelWarning(UserWarning):
    """A library was loaded before :mod:`anseg` with kernels other than the pinned ones."""


def isa_level(flags: set[str] | None = None) -> str:
    """The CPU's x86-64 microarchitecture level (``x86-64-v4`` for AVX-512, ``-v3`` for AVX2 and FMA), from its flags."""
    flags = cpu_flags() if flags is None else flags
    if platform.machine() not in ("x86_64", "AMD64") and not flags:
        return platform.machine()
    levels = [("x86-64-v4", {"avx512f", "avx512bw", "avx512cd", "avx512dq", "avx512vl"}),
              ("x86-64-v3", {"avx", "avx2", "bmi1", "bmi2", "f16c", "fma", "movbe", "xsave"}),
              ("x86-64-v2", {"cx16", "lahf_lm", "popcnt", "sse4_1", "sse4_2", "ssse3"})]
    reached = "x86-64"
    for name, needed in reversed(levels):
        if not needed <= flags:
            break
        reached = name
    return reached


def cpu_info(field: str) -> str | None:
    """The first CPU's ``field`` in ``/proc/cpuinfo`` (``model name``, ``flags``), or None where it is absent."""
    try:
        lines = Path("/proc/cpuinfo").read_text().splitlines()
    except OSError:
        return None
    return next((line.partition(":")[2].strip() for line in lines if line.split(":")[0].strip() == field), None)


def cpu_flags() -> set[str]:
    """The CPU's feature flags from ``/proc/cpuinfo`` (empty where that file is absent)."""
    return set((cpu_info("flags") or "").split())


def why_not_pinned() -> str | None:
    """Why this process runs the machine's own kernels (None where the pin applies)."""
    if os.environ.get(OPT_OUT, "").lower() == "native":
        return f"{OPT_OUT}=native"
    if platform.machine() not in ("x86_64", "AMD64"):
        return f"not x86-64 ({platform.machine()})"
    level = isa_level()
    if level not in ("x86-64-v3", "x86-64-v4"):
        return f"this CPU lacks AVX2 ({level})"
    return None


def pin_environment() -> str | None:
    """Set each variable of :data:`PIN` the user has not set, where the pin applies; why not (None where it does).

    Alone, for a process that must not import anseg yet (a benchmark that puts
    another revision's checkout first) but whose children and libraries should
    run the pinned kernels.
    """
    reason = why_not_pinned()
    if reason is None:
        for name, value in PIN.items():
            os.environ.setdefault(name, value)
    return reason


def native_environment(environ) -> dict[str, str]:
    """A copy of ``environ`` for a process that runs each library's own kernels: ``ANSEG_KERNELS=native`` and none of
    :data:`PIN`'s variables (which a process that imported anseg holds, and its children would inherit)."""
    return {**{name: value for name, value in environ.items() if name not in PIN}, OPT_OUT: "native"}


def pin() -> None:
    """Set each variable of :data:`PIN` the user has not set; warn once per library loaded earlier with other kernels."""
    reason = pin_environment()
    if reason is not None:
        if reason.startswith("this CPU") and "lacks" not in _warned:
            _warned.add("lacks")
            warnings.warn(f"anseg: {reason}: its kernels are the machine's own, so numbers may differ from the "
                          "project's", KernelWarning, stacklevel=2)
        return
    for library, drifted in _loaded_with_other_kernels().items():
        if drifted and library not in _warned:
            _warned.add(library)
            warnings.warn(f"anseg: {library} was loaded before anseg with its own kernels ({drifted}), not the "
                          f"pinned AVX2 ones: import anseg first, or set the variables of anseg.kernels.PIN before "
                          f"Python starts, for numbers that agree across CPUs", KernelWarning, stacklevel=3)


def _loaded_with_other_kernels() -> dict[str, str | None]:
    """For each library already loaded, the kernels it runs where they are not the ones :data:`PIN` asks for."""
    found: dict[str, str | None] = {}
    if "numpy" in sys.modules:
        dispatch = numpy_dispatch()
        found["NumPy"] = dispatch if dispatch not in (None, "X86_V3") else None
    if "torch" in sys.modules:
        capability = sys.modules["torch"].backends.cpu.get_cpu_capability()
        found["torch"] = capability if capability.lower() != os.environ["ATEN_CPU_CAPABILITY"] else None
    if "numba" in sys.modules:
        config = sys.modules["numba"].config
        found["numba"] = (config.CPU_NAME or "host CPU") if config.CPU_NAME != os.environ["NUMBA_CPU_NAME"] else None
    return found


def numpy_dispatch() -> str | None:
    """The highest SIMD target NumPy's loops dispatch to in this process (None before NumPy 2)."""
    try:
        from numpy._core import _multiarray_umath as umath
    except ImportError:
        return None
    active = [target for target in umath.__cpu_dispatch__ if umath.__cpu_features__.get(target)]
    return active[-1] if active else "baseline"


def in_force() -> dict:
    """The kernels this process runs, as a record keeps them: the pin, who set each variable, and each library's choice.

    Call it after the libraries have computed (a record is written after
    training): torch reports the capability it dispatched to, NumPy its SIMD
    target, and threadpoolctl the BLAS libraries loaded and the core type
    OpenBLAS chose for itself.
    """
    import torch
    from threadpoolctl import threadpool_info

    reason = why_not_pinned()
    variables = {name: os.environ[name] for name in PIN if name in os.environ}
    blas = sorted({f"{info.get('internal_api')} {info.get('version') or ''} {info.get('architecture') or ''}".strip()
                   for info in threadpool_info() if info.get("user_api") == "blas"})
    numba = sys.modules.get("numba")
    return {
        "pin": PIN_NAME if reason is None else f"none ({reason})",
        "isa": isa_level(),
        "set_by_user": sorted(name for name, value in variables.items() if reason is None and value != PIN[name]),
        "variables": variables,
        "torch": torch.backends.cpu.get_cpu_capability(),
        "numpy": numpy_dispatch(),
        "numba": None if numba is None else f"{numba.config.CPU_NAME or 'host'} {numba.config.CPU_FEATURES or ''}".strip(),
        "blas": blas,
    }


def feature_kernels() -> dict:
    """The kernels that decide the features' last bits, as the feature fingerprint keys them: NumPy's SIMD target and
    the CPU numba compiles for (the host's own where unpinned)."""
    numba_target = os.environ.get("NUMBA_CPU_NAME") or "host"
    if "NUMBA_CPU_FEATURES" in os.environ:
        numba_target += f" [{os.environ['NUMBA_CPU_FEATURES']}]"
    return {"kernels": {"numpy": numpy_dispatch(), "numba": numba_target}}
