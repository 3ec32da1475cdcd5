"""The study's releases: the installed packages are the lock file's, and a difference is named."""

from __future__ import annotations

import re

from anseg.study import releases
from anseg.study.store import REPO, environment


def test_the_installed_releases_are_the_locked_ones():
    """README's commands install requirements.lock; a package installed at another release fails here, by name."""
    assert releases.locked(), "requirements.lock is missing or holds no pins"
    assert releases.differences() == []


def test_a_release_other_than_the_locked_one_is_named(tmp_path):
    lock = tmp_path / "requirements.lock"
    lock.write_text("numpy==0.0.1 \\\n    --hash=sha256:00\n    # via anseg\nno-such-package-anseg==1.0\n")
    assert releases.locked(lock) == {"numpy": "0.0.1", "no-such-package-anseg": "1.0"}
    found = releases.differences(lock)
    assert found[0] == "no-such-package-anseg locked 1.0, installed none"
    assert re.fullmatch(r"numpy locked 0\.0\.1, installed \S+", found[1])
    assert releases.record(lock)["differ"] == found
    assert releases.record(tmp_path / "absent")["lock"] is None


def test_names_compare_as_pep_503_does():
    assert releases.canonical("Scikit_Learn") == releases.canonical("scikit.learn") == "scikit-learn"


def test_every_lock_line_pins_one_exact_release_with_its_hash():
    text = releases.LOCK.read_text()
    requirements = [line for line in text.splitlines() if line and not line.startswith((" ", "#"))]
    assert requirements and all("==" in line and line.endswith("\\") for line in requirements)
    assert text.count("--hash=sha256:") >= len(requirements)
    assert releases.locked()["torch"].startswith("2.13.0")  # pyproject's pin, the CPU build


def test_conda_installs_the_lock_too():
    """environment.yml brings Python and pip; the packages come from the lock, so the two paths cannot drift."""
    text = (REPO / "environment.yml").read_text()
    assert "- -r requirements.lock" in text
    dependencies = re.findall(r"^  - (\S+)$", text.split("dependencies:")[1], flags=re.M)
    assert dependencies == ["python=3.11", "pip", "pip:"]


def test_every_record_names_the_lock_and_the_kernels():
    env = environment()
    assert env["releases"] == releases.record()
    assert {"pin", "isa", "torch", "numpy", "blas", "variables"} <= set(env["kernels"])
