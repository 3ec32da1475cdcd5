"""Which code revisions, and which CPUs, a paired comparison reads.

A difference between two arms whose runs were trained by different code is
a difference of code as well: moving the code has moved single categories
by up to 0.8 points, the size of several effects the study judges. So a
table that pairs runs says which revisions each arm read (:func:`mix`), and
the claims ledger sets that sentence beside every paired verdict whose arms
do not share their revisions, with the drift measured between them:
``scripts/replay_run.py --at`` trains a sample of stored runs at each of those
revisions on one machine and keeps the accuracies in ``DRIFT``, so the
sentence says how far the same runs moved from one revision to another (on
one machine, since another CPU moves a run by itself), or that this was not
measured; and, since the file keeps each run's stored accuracy too, how many
moved from it on the replay machine (:func:`machine_drift`): the size of what
a change of CPU alone does, beside what a change of code did. For the same
reason a table or row whose arms were trained on different CPUs says so
(:func:`cpus`).
"""

from __future__ import annotations

import json
from collections import Counter
from pathlib import Path

SHOWN = 4  # arms named one by one in a sentence; a grid's others are counted
DRIFT = "replay/revision_drift.csv"  # under results/: runs trained at several revisions, one line per revision


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
            + drift(set().union(*by_arm.values()), results))


def drift(found: set[str], results: Path) -> str:
    """How far the runs of ``DRIFT`` moved between the revisions ``found`` (short, as :func:`revision` gives them).

    Reads the runs trained at every one of those revisions on one machine;
    a run's drift is its largest minus its smallest accuracy over them (unit
    area, points). Says "not measured" where no run was trained at all of them.
    """
    import pandas as pd

    path = Path(results) / DRIFT
    table = pd.read_csv(path, dtype={"at": str}) if path.is_file() else pd.DataFrame(columns=["at"])
    table = table.assign(at=table["at"].str[:7])
    absent = sorted(found - set(table["at"]))
    if absent:
        return f"the drift between them is not measured (no run of results/{DRIFT} was trained at {', '.join(absent)})"
    wide = table[table["at"].isin(found)].pivot_table(index=["key", "replayed_on"], columns="at", values="replayed",
                                                     aggfunc="first").dropna()
    if wide.empty:
        return f"the drift between them is not measured (no run of results/{DRIFT} was trained at all of them)"
    moved = (wide.max(axis=1) - wide.min(axis=1)) * 100
    machines = sorted(set(wide.index.get_level_values("replayed_on")))
    measured = (f"the {len(wide)} runs of results/{DRIFT} trained at each of them on one machine"
                f"{' each' if len(machines) > 1 else ''} ({' and '.join(machines)}) ")
    if (moved == 0).all():
        said = measured + "gave the same accuracy at every one, to the last digit"
    else:
        said = measured + f"moved by up to {moved.max():.2f} points between them (mean {moved.mean():.2f}; unit area)"
    machines = machine_drift(table)
    return f"{said}; {machines}" if machines else said


def machine_drift(table) -> str:
    """How many runs of ``DRIFT`` moved from their stored accuracy when retrained on the replay machine, with the one
    that moved most ("" where the file keeps no stored accuracy). The revisions did not move them where
    :func:`drift` says so; what moved them is the machine. The stored runs' records name no CPU model (``trained_on``
    reads "CPU"); docs/reproducibility.md has the evidence that they were trained on an AMD EPYC."""
    if "stored" not in table or "category" not in table:
        return ""
    runs = table.groupby("key").agg(category=("category", "first"), split=("split", "first"), stored=("stored", "first"),
                                    replayed=("replayed", "first"), on=("replayed_on", "first"))
    moved = runs[runs.stored != runs.replayed]
    machines = " and ".join(sorted(set(runs.on)))
    if moved.empty:
        return f"retrained on {machines}, all {len(runs)} gave their stored accuracy"
    most = moved.loc[(moved.replayed - moved.stored).abs().idxmax()]
    example = f"{most.category} split {most.split} {100 * most.stored:.2f} → {100 * most.replayed:.2f}"
    return (f"retrained on {machines}, {len(moved)} of the {len(runs)} moved from the accuracy stored on the CPU that "
            f"trained them (not recorded in the runs; an AMD EPYC, docs/reproducibility.md), most {example}")


def cpus(readings, results_dir: Path) -> str:
    """" " and what the run records say of the CPUs that trained each reading's runs, ``readings`` being (name,
    runs table with a ``key`` column) pairs: a table whose readings differ in CPU says so; where a record names none,
    what docs/reproducibility.md has as evidence instead."""
    from anseg.study.plan import PLAIN_READING
    from anseg.study.store import NOT_RECORDED, cpu_of

    found = {}
    for name, runs in readings:
        paths = [results_dir / "runs" / f"{key}.json" for key in runs.get("key", [])]
        found[name] = {cpu_of(json.loads(p.read_text())) for p in paths if p.is_file()}
    if not any(found.values()):
        return ""
    if any(NOT_RECORDED in cpus for cpus in found.values()):
        return (" The run records name no CPU model; docs/reproducibility.md has the evidence that the "
                f"`{PLAIN_READING}` runs were trained on an Intel Xeon and the default's in part on an AMD EPYC, so "
                "the two readings differ in CPU too.")
    if len(set().union(*found.values())) > 1:
        return " **These runs mix CPUs:** " + "; ".join(f"{n}: {', '.join(sorted(c))}" for n, c in found.items()) + "."
    return f" Every run trained on {next(iter(set().union(*found.values())))}."
