"""Which code revisions a paired comparison reads.

A difference between two arms whose runs were trained by different code is
a difference of code as well: moving the code has moved single categories
by up to 0.8 points, the size of several effects the study judges. So a
table that pairs runs says which revisions each arm read (:func:`mix`), and
the claims ledger sets that sentence beside every paired verdict whose arms
do not share their revisions; the drift between those revisions is not
measured here until the arms are retrained at one revision or replayed.
"""

from __future__ import annotations

import json
from collections import Counter
from pathlib import Path

SHOWN = 4  # arms named one by one in a sentence; a grid's others are counted


def revision(result: dict) -> str:
    """A stored result's code revision, short, marked when the code had uncommitted changes."""
    env = result.get("environment") or {}
    short = (env.get("code_revision") or "not recorded")[:7]
    return short + (" (uncommitted)" if env.get("code_clean") is False else "")


def run_revisions(keys, results: Path) -> list[str]:
    """The revision of each run key, read from ``results/runs/<key>.json`` ("not stored" where absent)."""
    out = []
    for key in keys:
        path = Path(results) / "runs" / f"{key}.json"
        out.append(revision(json.loads(path.read_text())) if path.is_file() else "not stored")
    return out


def mix(runs, arm: str, results: Path) -> str | None:
    """None when every arm of the table (column ``arm``) read runs of the same revisions; else one sentence naming them.

    ``runs`` is a run table with a ``key`` column (one row per run), as the
    notebooks write them; a table without keys names nothing.
    """
    if "key" not in runs:
        return None
    table = runs.assign(revision=run_revisions(runs["key"], results))
    by_arm = {name: tuple(sorted(set(group.revision))) for name, group in table.groupby(arm, sort=False)}
    sets = Counter(by_arm.values())
    if len(sets) <= 1:
        return None
    usual, count = sets.most_common(1)[0]
    others = [f"{name}: {', '.join(found)}" for name, found in by_arm.items() if found != usual or count == 1]
    listed = ([f"{count} of the {len(by_arm)} arms: {', '.join(usual)}"] if count > 1 else []) + others[:SHOWN]
    if len(others) > SHOWN:
        listed.append(f"{len(others) - SHOWN} more arms")
    return (f"the arms read runs of different code revisions ({'; '.join(listed)}); "
            "the drift between them is not measured")
