"""The kernel pin: set on import before the libraries load, the user's own settings kept, a late pin named."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from anseg import kernels

PRINT_STATE = "import json, anseg, torch; from anseg import kernels; torch.ones(2).exp(); print(json.dumps(kernels.in_force()))"


def run(code: str, **env: str) -> subprocess.CompletedProcess:
    clean = {k: v for k, v in os.environ.items() if k not in kernels.PIN and k != kernels.OPT_OUT}
    return subprocess.run([sys.executable, "-c", code],
                          env={**clean, **env}, capture_output=True, text=True, timeout=120, check=True)


needs_avx2 = pytest.mark.skipif(kernels.why_not_pinned() not in (None, f"{kernels.OPT_OUT}=native"),
                                reason=f"the pin applies to x86-64 CPUs with AVX2; here: {kernels.why_not_pinned()}")


@needs_avx2
def test_importing_anseg_pins_every_library_to_avx2():
    state = json.loads(run(PRINT_STATE).stdout)
    assert state["pin"] == kernels.PIN_NAME and state["variables"] == kernels.PIN
    assert state["torch"] == "AVX2" and state["numpy"] == "X86_V3" and state["set_by_user"] == []


@needs_avx2
def test_a_variable_the_user_set_is_kept_and_recorded():
    state = json.loads(run(PRINT_STATE, ATEN_CPU_CAPABILITY="default").stdout)
    assert state["torch"] == "DEFAULT" and state["set_by_user"] == ["ATEN_CPU_CAPABILITY"]
    assert state["variables"]["MKL_CBWR"] == kernels.PIN["MKL_CBWR"]


def test_native_leaves_every_library_its_own_choice():
    state = json.loads(run(PRINT_STATE, ANSEG_KERNELS="native").stdout)
    assert state["pin"] == "none (ANSEG_KERNELS=native)" and state["variables"] == {}


@needs_avx2
def test_a_library_loaded_before_anseg_is_named_once():
    done = run("import numpy, torch; torch.ones(2).exp(); import anseg; from anseg import kernels; kernels.pin()")
    warnings = [line for line in done.stderr.splitlines() if "KernelWarning" in line]
    assert len(warnings) == 2 and "NumPy was loaded before anseg" in warnings[0] and "torch was" in warnings[1]
    assert "Warning" not in run("import anseg, numpy, torch; torch.ones(2).exp()").stderr


def test_the_instruction_set_level_follows_the_flags():
    v3 = {"avx", "avx2", "bmi1", "bmi2", "f16c", "fma", "movbe", "xsave", "cx16", "lahf_lm", "popcnt", "sse4_1",
          "sse4_2", "ssse3"}
    assert kernels.isa_level(v3) == "x86-64-v3"
    assert kernels.isa_level(v3 | {"avx512f", "avx512bw", "avx512cd", "avx512dq", "avx512vl"}) == "x86-64-v4"
    assert kernels.isa_level(v3 - {"avx2"}) == "x86-64-v2"
    assert kernels.isa_level({"sse2"}) == "x86-64"


def test_the_feature_fingerprint_follows_numpys_kernels(monkeypatch):
    from anseg import features

    before = features.fingerprint()
    monkeypatch.setattr(kernels, "numpy_dispatch", lambda: "another SIMD target")
    assert features.fingerprint() != before
