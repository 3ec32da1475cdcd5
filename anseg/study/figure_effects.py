"""Each figure's paired effects, read from the table its notebook stores.

Table IV, Fig. 4, Fig. 11 and Fig. 12 each turn their stored runs into
paired effects over units (a (category, split), or a test mesh), judged by
the rule of :mod:`anseg.study.effects`. They live apart from the ledger so
that a figure's notebook and the ledger's row read the same numbers the
same way: the notebook writes its sentences from these functions, the
ledger its verdicts.
"""

from __future__ import annotations

from dataclasses import dataclass

from anseg.study import reference
from anseg.study.effects import Effect, MissingResult, effect


def by_unit(runs, *columns: str):
    """The run table indexed by (category, split), columns pivoted where given (the unit of every split claim)."""
    if columns:
        return runs.pivot_table(index=["category", "split"], columns=list(columns), values="unit_area")
    return runs.set_index(["category", "split"]).unit_area


def paired_over_splits(runs, better: str, worse: str) -> Effect:
    """Table IV's row ``better`` minus ``worse`` per (category, split), from its runs
    (``table4_ablation_runs.csv``: category, split, mode, unit_area), with the ledger's interval."""
    accuracy = by_unit(runs, "mode")
    return effect(accuracy[better] - accuracy[worse], f"{better} − {worse}")


def fig4_summary(meshes):
    """From Fig. 4's per-mesh table (``fig4_test_meshes.csv``): the means its tables show.

    The attention's mean AUC for near-boundary faces over the test meshes,
    by model and level of the nonuniform hierarchies (a Series), and the
    mean share of the area whose true label survives the trip to the
    coarsest level and back, by model and downsampling (a DataFrame).
    """
    auc = meshes[meshes.downsampling == "nonuniform"].groupby(["model", "level"])["attention AUC, near vs elsewhere"].mean()
    coarsest = meshes[meshes.level == meshes.level.max()]
    return auc, coarsest.groupby(["model", "downsampling"])["labels kept (%)"].mean().unstack()


def fig4_effects(meshes, model: str) -> tuple[Effect, Effect]:
    """The two claims Fig. 4 reads, per test mesh, for one reading (the rule of the ledger).

    Attention: the AUC of near-boundary faces minus 0.5 (chance), averaged
    over the coarse levels (1 and up) of the model's nonuniform hierarchy.
    Labels: the share of the area whose true label survives the coarsest
    level and back, nonuniform minus uniform. Where the table holds one
    trained model per split (its ``split`` column), the units are (split,
    mesh) and the bootstrap draws models, then meshes: one model's luck is
    part of the interval. One model: its test meshes, one stage.
    """
    own = meshes[meshes.model == model]
    units = ["split", "mesh"] if "split" in own and own["split"].nunique() > 1 else ["mesh"]
    nonuniform = own[(own.downsampling == "nonuniform") & (own.level > 0)]  # level 0 is the input mesh
    auc = nonuniform.groupby(units)["attention AUC, near vs elsewhere"].mean() - 0.5
    coarsest = own[own.level == own.level.max()].pivot_table(index=units, columns="downsampling", values="labels kept (%)")
    return (effect(auc, "AUC − 0.5"), effect(coarsest["nonuniform"] - coarsest["uniform"], "nonuniform − uniform"))


def cross_fitted_rivals(accuracy, key) -> dict:
    """Per split: the best point of the grid other than ``key``, by its mean over the OTHER splits.

    ``accuracy``: points (rows) by splits (columns). A rival picked by its
    mean over every split is scored on the runs that picked it, which
    favours it (the winner's curse: the best of many points is biased
    upwards); picked on the other splits, each split's rival is fixed before
    that split is read, so the paired difference carries no such bias.
    """
    others = accuracy.drop(key)
    return {split: others.drop(columns=split).mean(axis=1).idxmax() for split in accuracy.columns}


def describe_rivals(rivals: dict) -> str:
    """"N = 2, removing 0.3 (splits 0, 2); N = 3, removing 0.5 (split 1)": each rival and the splits it was picked for."""
    by_point: dict = {}
    for split, point in rivals.items():
        by_point.setdefault(point, []).append(split)
    return "; ".join(f"N = {n}, removing {r:g} (split{'s' if len(s) > 1 else ''} {', '.join(map(str, s))})"
                     for (r, n), s in by_point.items())


@dataclass(frozen=True)
class CyclesReading:
    """Fig. 11 read for one category, each effect over its splits with the ledger's rule.

    ``rise``: accuracy at the paper's N minus at N = 1, the mean over the
    shares removed; ``choice``: the paper's point (N = 4, removing 0.5) minus
    the best other point of the grid, picked for each split on the other
    splits (``rivals``: split -> (removed, cycles); :func:`cross_fitted_rivals`),
    None where the grid lacks the choice or holds one split (no rival could
    then be picked apart from the runs it is scored on).
    """

    category: str
    means: dict  # (removed, cycles) -> mean accuracy over the splits
    rise: Effect | None
    choice: Effect | None
    rivals: dict | None

    def __str__(self) -> str:
        best = max(self.means, key=self.means.get)
        text = (f"**{self.category}**: best point N = {best[1]}, removing {best[0]:g} ({self.means[best]:.2f} %); "
                "more cycles (the mean over the shares removed): ")
        text += "N = 1 or the paper's N not run" if self.rise is None else f"{self.rise} ({self.rise.verdict})"
        if self.choice is None:
            return text + "; the paper's choice not run, or one split (no rival picked apart from it)"
        return (text + f"; against the best other point picked on the other splits ({describe_rivals(self.rivals)}): "
                f"{self.choice} ({self.choice.verdict})")


def fig11_units(runs) -> dict:
    """Per category: (accuracy by (removed, cycles) × split, rise per split, choice per split or None, rivals)."""
    import pandas as pd

    choice = reference.FIG11_CHOICE
    key, first = (choice["removed"], choice["cycles"]), 1
    units = {}
    for category, table in runs.groupby("category"):
        accuracy = table.pivot_table(index=["removed", "cycles"], columns="split", values="unit_area")
        shares = [r for r in accuracy.index.unique("removed") if {(r, first), (r, choice["cycles"])} <= set(accuracy.index)]
        rise = None
        if shares:
            rise = sum(accuracy.loc[(r, choice["cycles"])] - accuracy.loc[(r, first)] for r in shares) / len(shares)
        gap, rivals = None, None
        if key in accuracy.index and len(accuracy) > 1 and len(accuracy.columns) > 1:
            rivals = cross_fitted_rivals(accuracy, key)
            gap = pd.Series({s: accuracy.loc[key, s] - accuracy.loc[point, s] for s, point in rivals.items()})
            gap.index.name = "split"
        units[category] = (accuracy, rise, gap, rivals)
    return units


def fig11_readings(runs) -> list[CyclesReading]:
    """Fig. 11's runs (``fig11_cycles_ratio.csv``: category, split, removed, cycles, unit_area) read per category.

    The Fig. 11 notebook writes its sentences from these; the ledger pools
    the same per-split effects over the categories (its cycles rows), so the
    figure and the ledger read the grid the same way.
    """
    choice = reference.FIG11_CHOICE
    return [CyclesReading(category, accuracy.mean(axis=1).to_dict(),
                          None if rise is None else effect(rise, f"N = {choice['cycles']} − N = 1"),
                          None if gap is None else effect(gap, "the paper's choice − the best other point"),
                          rivals)
            for category, (accuracy, rise, gap, rivals) in fig11_units(runs).items()]


def pooled(per_category: dict, name: str) -> Effect:
    """Per-split effects of several categories as one effect over (category, split)."""
    import pandas as pd

    present = {c: s for c, s in per_category.items() if s is not None}
    if not present:
        raise MissingResult(f"no category holds {name}")
    return effect(pd.concat(present, names=["category", "split"]), name)


def feature_effects(runs) -> tuple[Effect, Effect]:
    """Fig. 12's two claims per (category, split), from ``fig12_features.csv`` (category, split, features, unit_area).

    The full set (edge + GC + SDF + AGD) minus the best other of the paper's
    sets (picked per category by its mean over the splits, which favours it),
    and minus the set without AGD.
    """
    from anseg.features import ABLATION_SETS

    *others, full = list(ABLATION_SETS)
    accuracy = by_unit(runs, "features")
    rival = accuracy[others].groupby(level="category").mean().idxmax(axis=1)
    best_other = accuracy[others].apply(lambda row: row[rival[row.name[0]]], axis=1)
    return (effect(accuracy[full] - best_other, f"{full} − the best other set"),
            effect(accuracy[full] - accuracy[others[-1]], f"{full} − {others[-1]}"))
