"""Finding the benchmark data: the data root, and archives verified and extracted once.

A data set sits under the data root either as its extracted folder (say
``<root>/human_seg/``) or as the archive its distribution ships
(``<root>/human_seg.tar.gz``). The folder wins when both exist. An archive is
checked against its known sha256, then extracted once into
``cache_dir("datasets")/<first 16 hex digits of the sha256>/``:

* the hash is computed once per archive file; a marker keyed by the file's
  path, size and mtime remembers that it matched;
* extraction goes to a temporary folder beside the target, a completion
  marker is written last, and the folder is renamed into place, so a crash
  never leaves a folder that looks complete (one without the marker is
  removed and extracted again);
* members with absolute paths, ``..`` components, links or device entries
  are refused.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import tarfile
import tempfile
from pathlib import Path, PurePosixPath

from anseg.cache import atomic_write, cache_dir

# The archives of the benchmark data as distributed, and their sha256.
KNOWN_ARCHIVES = {
    "psb_labeled.tar.gz": "e19883a7035e60e28d70b12db9c29ab7348bf96cb6ff43fb527b0190054434c3",
    "coseg.tar.gz": "6fc39c59bf39345799888adf1fe1effb7d81969691f55f6fcee9a8dc1f347bad",
    "human_seg.tar.gz": "7b33aa9d0c709261f2e38fe3283b1fd2e37379554562254b5a58b88886be95ec",
}
COMPLETE_MARKER = ".anseg-extracted"
HINT = (
    "point anseg at the folder holding psb_labeled.tar.gz, coseg.tar.gz and human_seg.tar.gz "
    "(or their extracted folders) with the ANSEG_DATA environment variable or the root= argument"
)


class DatasetError(Exception):
    """Benchmark data that is missing, corrupt or malformed, or a request for data that does not exist."""


def data_root(root: str | os.PathLike | None = None) -> Path:
    """The folder holding the data sets: ``root`` when given, else ``$ANSEG_DATA``."""
    if root is None:
        root = os.environ.get("ANSEG_DATA")
        if not root:
            raise DatasetError(f"no data folder given: {HINT}")
        source = "ANSEG_DATA"
    else:
        source = "root="
    path = Path(root).expanduser()
    if not path.is_dir():
        raise DatasetError(f"data folder {path} (from {source}) does not exist or is not a folder; {HINT}")
    return path


def dataset_folder(root: Path, folder: str, archive: str | None = None) -> Path:
    """``<root>/<folder>`` if it exists, else that folder inside ``<root>/<archive>``, extracted once."""
    extracted = root / folder
    if extracted.is_dir():
        return extracted
    if archive is not None and (root / archive).is_file():
        path = root / archive
        expected = KNOWN_ARCHIVES[archive]
        verify_archive(path, expected)
        inside = extract_archive(path, expected) / folder
        if not inside.is_dir():
            raise DatasetError(f"{path} holds no {folder}/ folder")
        return inside
    wanted = f"neither {extracted}/ nor {root / archive} exists" if archive else f"{extracted}/ does not exist"
    raise DatasetError(f"data set not found: {wanted}; {HINT}")


def _sha256_of(path: Path) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as stream:
        for block in iter(lambda: stream.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def verify_archive(path: Path, expected_sha256: str) -> None:
    """Raise DatasetError unless the file's sha256 is ``expected_sha256``; hash a given file version only once."""
    stat = path.stat()
    key = hashlib.sha256(f"{path.resolve()}|{stat.st_size}|{stat.st_mtime_ns}".encode()).hexdigest()[:24]
    marker = cache_dir("datasets", "verified") / f"{path.name}.{key}"
    if marker.is_file() and marker.read_text().strip() == expected_sha256:
        return
    found = _sha256_of(path)
    if found != expected_sha256:
        raise DatasetError(
            f"{path}: sha256 is {found}, expected {expected_sha256}: "
            "the file is damaged or is not the archive anseg knows; fetch it again"
        )
    atomic_write(marker, lambda tmp: tmp.write_text(found + "\n"))


def _check_member(archive: Path, member: tarfile.TarInfo) -> None:
    name = PurePosixPath(member.name)
    if name.is_absolute() or ".." in name.parts:
        raise DatasetError(f"{archive}: refusing to extract member {member.name!r} (absolute path or '..')")
    if not (member.isfile() or member.isdir()):
        raise DatasetError(f"{archive}: refusing to extract member {member.name!r} (a link or special file)")


def extract_archive(path: Path, sha256: str) -> Path:
    """Extract the tar archive ``path`` (of known ``sha256``) into the cache once; return the folder."""
    target = cache_dir("datasets") / sha256[:16]
    if (target / COMPLETE_MARKER).is_file():
        return target
    if target.exists():  # left by an interrupted extraction: start again
        shutil.rmtree(target)
    tmp = Path(tempfile.mkdtemp(dir=target.parent, prefix=f".{target.name}-"))
    # the "data" filter (Python >= 3.12, and late 3.10/3.11 patch releases) adds the stdlib's own checks
    filter_kw = {"filter": "data"} if hasattr(tarfile, "data_filter") else {}
    try:
        with tarfile.open(path, "r:*") as tar:
            for member in tar:  # one pass over the compressed stream: check, then extract
                _check_member(path, member)
                tar.extract(member, tmp, **filter_kw)
        (tmp / COMPLETE_MARKER).write_text(f"{path.name} {sha256}\n")
        try:
            os.rename(tmp, target)
        except OSError:
            if not (target / COMPLETE_MARKER).is_file():  # not another process finishing first
                raise
            shutil.rmtree(tmp)
    except BaseException as exc:
        shutil.rmtree(tmp, ignore_errors=True)
        if isinstance(exc, tarfile.TarError):
            raise DatasetError(f"{path}: not a readable tar archive ({exc})") from exc
        raise
    return target
