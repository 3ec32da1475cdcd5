"""Where anseg keeps what it derives (extracted archives, features, eigenbases), atomic writes, and checked arrays.

The location is ``$ANSEG_CACHE`` when set, else ``$XDG_CACHE_HOME/anseg``,
else ``~/.cache/anseg``. Every write goes to a temporary file in the same
folder and is renamed into place, so a crash never leaves a half-written
entry under the final name. Cached arrays end with the sha256 of their data,
so flipped bytes are caught on reading, not trained on.
"""

from __future__ import annotations

import hashlib
import os
import tempfile
import warnings
from collections.abc import Callable, Mapping
from functools import cache
from importlib import metadata
from pathlib import Path

import numpy as np


def cache_dir(*parts: str) -> Path:
    """The cache folder (or a sub-folder of it), created on first use."""
    base = os.environ.get("ANSEG_CACHE")
    if base:
        root = Path(base).expanduser()
    else:
        xdg = os.environ.get("XDG_CACHE_HOME")
        root = (Path(xdg).expanduser() if xdg else Path.home() / ".cache") / "anseg"
    path = root.joinpath(*parts)
    path.mkdir(parents=True, exist_ok=True)
    return path


# The compiled libraries whose arithmetic the cached arrays come from: a new release may round otherwise.
NUMERIC_LIBRARIES = ("numpy", "scipy", "libigl", "potpourri3d", "numba", "embreex", "pyamg")


@cache
def library_versions() -> dict[str, str | None]:
    """The installed version of each of :data:`NUMERIC_LIBRARIES` (None where absent), part of every cache key.

    A cache entry is an array some code computed; the key names that code, so
    that a cache filled by other releases is never read as if ours had made it.
    """
    versions = {}
    for name in NUMERIC_LIBRARIES:
        try:
            versions[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            versions[name] = None
    return versions


def _umask() -> int:
    """The process umask. Python reads it only by setting another, so the strictest is set
    for that instant (a file another thread creates meanwhile is too private, never too open)."""
    mask = os.umask(0o077)
    os.umask(mask)
    return mask


def atomic_write(path: str | os.PathLike, write: Callable[[Path], None]) -> Path:
    """Call ``write(tmp_path)`` and rename the result to ``path``; the temporary file never survives a failure.

    The file gets the permissions the umask gives any new file (0666 & ~umask),
    not the owner-only 0600 of the temporary file, so that outputs can be shared as usual.
    """
    atomic_write_all({Path(path): write})
    return Path(path)


def atomic_write_all(writes: Mapping[Path, Callable[[Path], None]]) -> None:
    """Write several files as one: each to a temporary file beside its target, renamed into place only when all are written.

    A failure or an interruption before the renames leaves every existing
    file as it was and no temporary file behind, so that a command's outputs
    never mix two runs. An OSError names the target, never the temporary
    file, whose name means nothing to whoever chose the target. The renames,
    each within its target's folder, are the one step not undone.
    """
    staged: list[tuple[Path, Path]] = []
    path = None
    try:
        for path, write in writes.items():
            path = Path(path)
            path.parent.mkdir(parents=True, exist_ok=True)
            # the temporary name ends like the final one, for writers that pick the format by suffix
            fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=f".tmp{path.suffix}")
            os.close(fd)
            staged.append((Path(tmp), path))
            write(Path(tmp))
            os.chmod(tmp, 0o666 & ~_umask())
        for tmp, path in staged:
            os.replace(tmp, path)
    except OSError as exc:
        raise OSError(exc.errno, exc.strerror or str(exc), str(path)) from exc  # the errno picks the subclass
    finally:
        for tmp, _ in staged:
            tmp.unlink(missing_ok=True)


def write_checked_array(path: Path, array: np.ndarray) -> None:
    """The array as .npy, then the sha256 of its data (use inside :func:`atomic_write`)."""
    with open(path, "wb") as handle:  # np.save(path) would append ".npy" to the temporary name
        np.save(handle, array, allow_pickle=False)
        handle.write(hashlib.sha256(np.ascontiguousarray(array).tobytes()).digest())


def read_checked_array(path: Path, shape: tuple[int, int]) -> np.ndarray | None:
    """The float32 array written by :func:`write_checked_array`, or None when absent.

    A damaged entry (checksum, shape, dtype or non-finite values) is removed,
    with a RuntimeWarning, and None returned, so that the caller recomputes it.
    """
    if not path.is_file():
        return None
    try:
        with open(path, "rb") as handle:
            array = np.lib.format.read_array(handle, allow_pickle=False)
            checksum = handle.read()
        problem = None
        if checksum != hashlib.sha256(array.tobytes()).digest():
            problem = "checksum mismatch (damaged or truncated)"
        elif array.shape != shape:
            problem = f"shape {array.shape}, expected {shape}"
        elif array.dtype != np.float32:
            problem = f"dtype {array.dtype}, expected float32"
        elif not np.isfinite(array).all():
            problem = "non-finite values"
    except (OSError, ValueError, EOFError) as exc:
        problem = f"unreadable ({type(exc).__name__}: {exc})"
    if problem is None:
        return array
    warnings.warn(f"damaged cache entry {path}: {problem}; recomputing", RuntimeWarning, stacklevel=3)
    path.unlink(missing_ok=True)
    return None
