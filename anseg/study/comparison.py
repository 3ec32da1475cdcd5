"""How a validation study's arms compare: paired differences over categories x folds, their cost, the seeds' spread.

The numbers :mod:`anseg.study.validate` prints and writes for a study: per arm and
category the mean held-out accuracy (Eq. 5, unit area) beside the accuracy on
the cells' own training meshes, the suite mean (the
mean over categories) with the spread of that mean over the fold x seed
replicates, and for each arm against the baseline the paired difference: per
(category, fold) the mean over seeds of arm minus baseline, averaged, with a
95 % percentile interval from a two-stage bootstrap (categories resampled
with replacement, then the folds inside each drawn category), and what the
arm's training costs: its CPU seconds over the baseline's on the cells both
trained, and the code revisions each arm's cells ran. The decision rule
(:func:`verdict`) depends on what the arm is for. An arm for accuracy is adopted
when its interval lies above 0. An arm that removes a defect (labels that depend
on pose, face or vertex order, threads or the machine) is adopted when it is
non-inferior: the interval's lower end above -:data:`NON_INFERIORITY_MARGIN`
points. A user needs such a fix to cost no accuracy, not to add some, and the
suite mean moves 0.3 points from seed to seed. The rule for fixes was added
after the grad-pose confirm had been read (see docs/choosing-settings.md).
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from anseg.cache import atomic_write

BOOTSTRAP_SAMPLES = 10_000
MIN_CATEGORIES = 3  # fewer give a bootstrap interval that is no interval at all
NON_INFERIORITY_MARGIN = 0.5  # points: how much held-out accuracy a fix of a defect may cost at the interval's lower end
PURPOSES = ("accuracy", "fix")


def verdict(comparison: dict, purpose: str = "accuracy") -> str:
    """The rule applied to one paired comparison: ``adopt``, ``worse``, ``no evidence``, or no verdict on too few categories.

    ``purpose`` is ``accuracy`` (adopt when the interval lies above 0) or
    ``fix``, for an arm that removes a defect (adopt when the lower end lies
    above -:data:`NON_INFERIORITY_MARGIN`).
    """
    if purpose not in PURPOSES:
        raise ValueError(f"purpose is one of {', '.join(PURPOSES)}, got {purpose!r}")
    if comparison["categories"] < MIN_CATEGORIES:
        return f"no verdict on fewer than {MIN_CATEGORIES} categories"
    floor = -NON_INFERIORITY_MARGIN if purpose == "fix" else 0.0
    if comparison["low"] > floor:
        return "adopt" if purpose == "accuracy" else f"adopt (non-inferior: lower end above {floor:+.1f})"
    return "worse" if comparison["high"] < 0 else "no evidence"


def accuracy_table(results: list[dict]) -> dict[tuple[str, str, int, int], float]:
    """(arm, category, fold, seed) -> held-out accuracy in % (Eq. 5, unit area, as the arm segments)."""
    return {(r["arm"], r["category"], r["fold"], r["seed"]): 100 * r["accuracy"]["unit_area"] for r in results}


def paired_difference(table: dict, arm: str, baseline: str, samples: int = BOOTSTRAP_SAMPLES, seed: int = 0) -> dict:
    """Arm minus baseline over the (category, fold) cells both have, seeds averaged inside a cell.

    Returns the mean difference, its 95 % two-stage bootstrap interval
    (categories, then folds inside each category, resampled with
    replacement) and the number of categories and paired cells.
    """
    pairs: dict[str, dict[int, list[float]]] = {}
    for (name, category, fold, seed_), value in table.items():
        other = table.get((baseline, category, fold, seed_))
        if name == arm and other is not None:
            pairs.setdefault(category, {}).setdefault(fold, []).append(value - other)
    if not pairs:
        return {"arm": arm, "baseline": baseline, "mean": float("nan"), "low": float("nan"), "high": float("nan"),
                "categories": 0, "cells": 0}
    per_category = [np.array([np.mean(v) for v in folds.values()]) for folds in pairs.values()]
    mean = float(np.mean([d.mean() for d in per_category]))
    rng = np.random.default_rng(seed)
    draws = np.empty(samples)
    for b in range(samples):
        chosen = rng.integers(0, len(per_category), len(per_category))
        draws[b] = np.mean([rng.choice(per_category[c], len(per_category[c])).mean() for c in chosen])
    low, high = np.percentile(draws, [2.5, 97.5])
    return {"arm": arm, "baseline": baseline, "mean": mean, "low": float(low), "high": float(high),
            "categories": len(per_category), "cells": int(sum(len(d) for d in per_category))}


def training_cost(results: list[dict], arm: str, baseline: str) -> float:
    """The arm's training CPU seconds over the baseline's, summed over the cells both trained (NaN without any).

    CPU time of the training process, not wall time: a cell that waited
    beside other jobs, or was paused, costs what it computed.
    """
    def seconds(name):
        return {(r["category"], r["fold"], r["seed"]): r["train_cpu_seconds"] for r in results
                if r["arm"] == name and r.get("trained") and "train_cpu_seconds" in r}

    ours, theirs = seconds(arm), seconds(baseline)
    shared = ours.keys() & theirs.keys()
    if not shared:
        return float("nan")
    return sum(ours[c] for c in shared) / sum(theirs[c] for c in shared)


def training_fit(results: list[dict], arm: str, category: str) -> float:
    """The arm's mean accuracy in % on its own training meshes in that category (NaN where no cell recorded it).

    Beside the held-out accuracy it tells bias from variance: a network that
    cannot fit its training meshes needs optimisation or information, not regularisation.
    """
    values = [100 * r["train_accuracy"]["unit_area"] for r in results
              if r["arm"] == arm and r["category"] == category and "train_accuracy" in r]
    return float(np.mean(values)) if values else float("nan")


def revisions(results: list[dict], arm: str) -> str:
    """The code revisions an arm's cells were trained at, short and sorted ("+" where the code differed from its
    commit, "?" where a cell recorded none).

    A paired difference reads like with like only where both arms ran one
    revision: moving the code can move a cell as much as the effects judged.
    """
    found = set()
    for r in results:
        if r["arm"] == arm:
            machine = r.get("environment", {})
            found.add((machine.get("code_revision") or "?")[:7] + ("+" if machine.get("code_clean") is False else ""))
    return " ".join(sorted(found))


def seed_spread(table: dict) -> list[dict]:
    """How far each arm moves from seed to seed, over the (category, fold) cells run with two seeds or more.

    Per arm: the median and the largest range (max - min over seeds) of a
    cell's accuracy, and the range of the suite mean (categories averaged,
    each over its folds) from seed to seed, on the cells every seed has.
    """
    rows = []
    for arm in sorted({k[0] for k in table}):
        by_cell: dict[tuple[str, int], dict[int, float]] = {}
        for (name, category, fold, seed), value in table.items():
            if name == arm:
                by_cell.setdefault((category, fold), {})[seed] = value
        seeds = sorted({s for values in by_cell.values() for s in values})
        shared = {cell: values for cell, values in by_cell.items() if len(values) == len(seeds)}
        if len(seeds) < 2 or not shared:
            continue
        ranges = [max(v.values()) - min(v.values()) for v in shared.values()]
        categories = sorted({category for category, _ in shared})
        suite = [np.mean([np.mean([v[s] for (c, _), v in shared.items() if c == category]) for category in categories])
                 for s in seeds]
        rows.append({"arm": arm, "seeds": len(seeds), "cells": len(shared), "median_range": float(np.median(ranges)),
                     "max_range": float(np.max(ranges)), "suite_mean_range": float(np.ptp(suite))})
    return rows


def summarize(results: list[dict], baseline: str, fixes: tuple[str, ...] = ()) -> tuple[list[dict], list[dict]]:
    """Per arm and category (and the suite mean) rows, and each arm's paired comparison with the baseline, with its
    purpose (``fix`` for the arms named in ``fixes``) and the rule's verdict."""
    table = accuracy_table(results)
    arms = sorted({k[0] for k in table}, key=lambda a: (a != baseline, a))
    categories = sorted({k[1] for k in table})
    rows = []
    for arm in arms:
        cells = {k: v for k, v in table.items() if k[0] == arm}
        for category in categories:
            values = [v for k, v in cells.items() if k[1] == category]
            if values:
                rows.append({"arm": arm, "category": category, "mean": float(np.mean(values)),
                             "std": float(np.std(values, ddof=1)) if len(values) > 1 else float("nan"), "runs": len(values),
                             "train_mean": training_fit(results, arm, category)})
        replicates = {}
        for (_, category, fold, seed), value in cells.items():
            replicates.setdefault((fold, seed), {})[category] = value
        complete = [np.mean(list(r.values())) for r in replicates.values() if len(r) == len(categories)]
        means = [row["mean"] for row in rows if row["arm"] == arm]
        fits = [row["train_mean"] for row in rows if row["arm"] == arm]
        rows.append({"arm": arm, "category": "suite mean", "mean": float(np.mean(means)),
                     "std": float(np.std(complete, ddof=1)) if len(complete) > 1 else float("nan"), "runs": len(cells),
                     "train_mean": float(np.mean(fits))})
    comparisons = [{**paired_difference(table, arm, baseline), "cost": training_cost(results, arm, baseline),
                    "revisions": revisions(results, arm), "baseline_revisions": revisions(results, baseline)}
                   for arm in arms if arm != baseline]
    for c in comparisons:
        c["purpose"] = "fix" if c["arm"] in fixes else "accuracy"
        c["verdict"] = verdict(c, c["purpose"])
    return rows, comparisons


def write_report(results: list[dict], baseline: str, out: str | Path, study: str, fixes: tuple[str, ...] = ()) -> str:
    """Write ``<out>/<study>_accuracy.csv``, ``_paired.csv`` (and ``_seeds.csv`` with several seeds);
    return the report as text. The arms named in ``fixes`` are judged by the rule for fixes (:func:`verdict`)."""
    rows, comparisons = summarize(results, baseline, fixes)
    spread = seed_spread(accuracy_table(results))
    out = Path(out)
    for name, table in (("accuracy", rows), ("paired", comparisons), ("seeds", spread)):
        if table:
            text = csv_text(table)
            atomic_write(out / f"{study}_{name}.csv", lambda tmp, text=text: tmp.write_text(text))
    lines = [f"{'arm':<24} {'category':<12} {'mean':>7} {'std':>6} {'runs':>4} {'on its training meshes':>22}"]
    lines += [f"{r['arm']:<24} {r['category']:<12} {r['mean']:7.2f} {r['std']:6.2f} {r['runs']:4d} {r['train_mean']:22.2f}"
              for r in rows]
    if comparisons:
        lines.append(f"\npaired difference against {baseline!r} (95 % bootstrap over categories, then folds):")
        if len({r["seed"] for r in results}) == 1:
            lines.append("  (one seed: the interval leaves out the spread from seed to seed; a screen, not a verdict)")
        for c in comparisons:
            cost = f"; training costs {c['cost']:.2f}x the baseline's CPU time" if np.isfinite(c["cost"]) else ""
            mixed = (f"; trained at {c['revisions']}, the baseline at {c['baseline_revisions']}"
                     if c["revisions"] != c["baseline_revisions"] or " " in c["revisions"] else "")
            lines.append(f"  {c['arm']:<24} {c['mean']:+6.2f} [{c['low']:+6.2f}, {c['high']:+6.2f}] "
                         f"({c['categories']} categories, {c['cells']} cells), {c['purpose']}: {c['verdict']}{cost}{mixed}")
    if spread:
        lines.append("\nfrom seed to seed (range over seeds: of one cell's accuracy, median and largest; of the suite mean):")
        lines += [f"  {r['arm']:<24} {r['median_range']:5.2f} median, {r['max_range']:5.2f} largest over {r['cells']} cells; "
                  f"suite mean {r['suite_mean_range']:5.2f} ({r['seeds']} seeds)" for r in spread]
    return "\n".join(lines)


def write_ensemble_report(ensembles: list[dict], results: list[dict], baseline: str, out: str | Path, study: str) -> str:
    """Write ``<out>/<study>_ensemble.csv`` (:func:`ensemble_comparisons`); return it as text."""
    rows = ensemble_comparisons(ensembles, results, baseline)
    text = csv_text(rows)
    atomic_write(Path(out) / f"{study}_ensemble.csv", lambda tmp: tmp.write_text(text))
    lines = ["\nseeds together (class probabilities averaged), paired over categories x folds:"]
    lines += [f"  {r['arm']:<16} against {r['against']:<36} {r['mean']:+6.2f} [{r['low']:+6.2f}, {r['high']:+6.2f}] "
              f"({r['categories']} categories, {r['cells']} cells)" for r in rows]
    return "\n".join(lines)


def csv_text(rows: list[dict]) -> str:
    """Rows of dicts as CSV text (floats with 4 decimals), the header from the first row."""
    import io

    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=list(rows[0]), lineterminator="\n")
    writer.writeheader()
    writer.writerows([{k: (f"{v:.4f}" if isinstance(v, float) else v) for k, v in row.items()} for row in rows])
    return buffer.getvalue()


def ensemble_comparisons(ensembles: list[dict], results: list[dict], baseline: str) -> list[dict]:
    """Per arm, its ensemble against the mean of its single models, and against the baseline's single models.

    Paired over the (category, fold) cells, with the same two-stage bootstrap
    as :func:`paired_difference`.
    """
    singles: dict[tuple[str, str, int], list[float]] = {}
    for (arm, category, fold, _), value in accuracy_table(results).items():
        singles.setdefault((arm, category, fold), []).append(value)
    rows = []
    for arm in sorted({e["arm"] for e in ensembles}):
        seeds = max(len(e["seeds"]) for e in ensembles if e["arm"] == arm)
        name = f"{arm} x{seeds}"
        table = {(name, e["category"], e["fold"], 0): 100 * e["accuracy"]["unit_area"] for e in ensembles if e["arm"] == arm}
        for against in dict.fromkeys((arm, baseline)):
            table.update({(against, c, f, 0): float(np.mean(v)) for (a, c, f), v in singles.items() if a == against})
            rows.append({**paired_difference(table, name, against), "against": f"{against}, one model (seeds averaged)"})
    return rows
