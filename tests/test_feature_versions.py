"""Each feature group's output on a fixed mesh is pinned to its version: a change of output needs a new version.

The feature cache and every stored run are keyed by the groups' versions
(:func:`anseg.features.fingerprint`). A change that moves a group's output,
however little, without raising :data:`anseg.features.GROUP_VERSIONS` would let
a cache serve features of other code, and a stored result would no longer
replay. ``tests/data/feature_digests.json`` holds, per group, the version, the
sha256 of its float32 output on :func:`fixed_mesh` and the kernels that computed
it (NumPy's AVX-512 loops give ``gc`` other last bits than the pinned AVX2
ones); it is written by ``python tests/test_feature_versions.py`` after a
version is raised.
"""

from __future__ import annotations

import anseg  # noqa: F401  first: the pin is set before NumPy loads (run as a script too)

# isort: split
import hashlib
import json
import sys
from pathlib import Path

import numpy as np
import trimesh

from anseg import features, kernels
from anseg.mesh import Mesh

RECORD = Path(__file__).parent / "data" / "feature_digests.json"


def fixed_mesh() -> Mesh:
    """A closed, stretched, bumpy sphere (1280 faces) made by code alone: no symmetry, so no ties to break."""
    sphere = trimesh.creation.icosphere(subdivisions=3)
    bumps = 1.0 + 0.05 * np.sin(3.0 * sphere.vertices[:, 0]) * np.cos(2.0 * sphere.vertices[:, 1])
    return Mesh(sphere.vertices * bumps[:, None] * [1.7, 1.0, 0.6], sphere.faces)


def digests(mesh: Mesh) -> dict[str, str]:
    """The sha256 of each group's float32 output on ``mesh``, computed alone (no cache)."""
    return {group: hashlib.sha256(np.ascontiguousarray(block).tobytes()).hexdigest()
            for group, block in features.compute_groups(mesh, features.GROUPS, cache=False).items()}


def stale_groups(record: dict, computed: dict[str, str]) -> list[str]:
    """The groups whose recorded version and digest disagree with the code's, each as a sentence."""
    problems, here = [], kernels.feature_kernels()["kernels"]
    for group, digest in computed.items():
        entry, version = record.get(group, {}), features.GROUP_VERSIONS[group]
        if entry.get("version") == version and entry.get("digest") != digest:
            problems.append(f"{group}: recorded under the kernels {entry.get('kernels')}, computed under {here}"
                            if entry.get("kernels") != here else
                            f"{group}: its output changed at version {version}; raise GROUP_VERSIONS[{group!r}]")
        elif entry.get("version") != version:
            problems.append(f"{group}: version {version} is not recorded; rewrite the record "
                            "(python tests/test_feature_versions.py)")
    return problems


def test_every_group_output_matches_the_digest_of_its_version():
    assert stale_groups(json.loads(RECORD.read_text()), digests(fixed_mesh())) == []


def test_a_changed_output_at_the_same_version_fails(monkeypatch):
    record = json.loads(RECORD.read_text())
    edge = features._GROUP_FUNCTIONS["edge"]
    monkeypatch.setitem(features._GROUP_FUNCTIONS, "edge", lambda g: edge(g) * (1 + 1e-6))
    assert stale_groups(record, digests(fixed_mesh())) == \
        ["edge: its output changed at version 1; raise GROUP_VERSIONS['edge']"]


def test_a_raised_version_changes_the_fingerprint_that_keys_the_cache(monkeypatch):
    before = features.fingerprint()
    monkeypatch.setitem(features.GROUP_VERSIONS, "hks", features.GROUP_VERSIONS["hks"] + 1)
    assert features.fingerprint() != before


if __name__ == "__main__":
    computed = digests(fixed_mesh())
    RECORD.write_text(json.dumps({g: {"version": features.GROUP_VERSIONS[g], "digest": d,
                                      "kernels": kernels.feature_kernels()["kernels"]} for g, d in computed.items()},
                                 indent=1) + "\n")
    print(f"wrote {RECORD}", file=sys.stderr)
