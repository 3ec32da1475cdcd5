"""The releases the study runs on: the lock file's exact versions, and where the installed ones differ.

Why: NumPy, SciPy, libigl and torch round otherwise from release to release,
and the collapse turns a last-bit difference into other labels, so a number
replays only on the releases that made it. ``requirements.lock`` (made with
pip-tools, ``make lock``) holds every package the study installs, with
hashes; README's two commands install it. ``pyproject.toml`` keeps ranges for
those who use anseg as a library. Every record names the lock's digest and
the packages installed otherwise (:func:`record`).
"""

from __future__ import annotations

import hashlib
import re
from importlib import metadata
from pathlib import Path

LOCK = Path(__file__).resolve().parents[2] / "requirements.lock"
_PIN = re.compile(r"^([A-Za-z0-9][A-Za-z0-9._-]*)==([^\s\\;]+)")


def canonical(name: str) -> str:
    """A distribution's name as PEP 503 compares them (``Scikit_Learn`` and ``scikit-learn`` alike)."""
    return re.sub(r"[-_.]+", "-", name).lower()


def locked(lock: Path = LOCK) -> dict[str, str]:
    """Each package of the lock file and its exact version (empty where the file is absent: a library install)."""
    if not lock.is_file():
        return {}
    pins = (_PIN.match(line) for line in lock.read_text().splitlines())
    return {canonical(m.group(1)): m.group(2) for m in pins if m}


def differences(lock: Path = LOCK) -> list[str]:
    """The locked packages installed at another version or not at all, each as ``name locked X, installed Y``."""
    found = []
    for name, version in sorted(locked(lock).items()):
        try:
            installed = metadata.version(name)
        except metadata.PackageNotFoundError:
            installed = "none"
        if installed != version:
            found.append(f"{name} locked {version}, installed {installed}")
    return found


def record(lock: Path = LOCK) -> dict:
    """What a result keeps of its releases: the lock's sha256 (short) and the packages installed otherwise."""
    if not lock.is_file():
        return {"lock": None, "differ": ["no lock file: releases as installed"]}
    return {"lock": hashlib.sha256(lock.read_bytes()).hexdigest()[:16], "differ": differences(lock)}
