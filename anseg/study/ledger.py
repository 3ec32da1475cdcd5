"""The claims ledger: every claim of the paper, our verdict and the evidence that decides it, read from ``results/``.

One row per claim: what the paper says, what our stored results say, and a
verdict. Every number comes from the result files the notebooks write
(``results/*.csv``, the run records of ``results/runs/``); a missing file
makes its claim ``cannot be tested here`` and says which.

One rule for every row (:data:`RULE`, shown above the table): the claim
becomes a paired effect in its favour, over units (a (category, split), or a
test mesh); its mean and 95 % percentile bootstrap interval
(:mod:`anseg.study.effects`; two-stage over categories, then the splits inside
each) read ``reproduced`` above 0, ``not reproduced`` below 0, ``not
distinguishable`` when it holds 0 or rests on one unit; a claim of several
parts needs every part. One rule, so that a tie reads the same in every row
and a difference is judged against its own spread; two-stage, because
categories differ far more than splits. A claim that names a number becomes
ours minus that number.

Two readings, one rule over both: the ablation claims (Table IV, Fig. 4,
Fig. 11, Fig. 12) are decided where the default departs from the paper's
method as written, so each is read twice: literally, on the ``paper``
configuration (the method as written), and at our strongest, on the
default. Each reading gets its verdict by the rule above; the row reads that
verdict where the two agree and ``depends on the reading`` where they do not
(:func:`anseg.study.effects.across_readings`), both effects beside it: a
claim that holds under one reading alone is neither reproduced nor refuted.
Until every run of the literal reading is stored such a row is not tested
(part of the runs must not stand for all).

What a row also says, since a reader weighs the evidence by it: where the
arms read runs of other code revisions, which, and how far the replayed
runs moved between revisions and between machines
(:mod:`anseg.study.revisions`); where it reads PSB splits 1-4, how many of
their test meshes the settings were chosen on (:mod:`anseg.study.selection`).
The README shows each row in short (``in short``, about 60 words); the
claims_ledger notebook and ``results/claims_ledger.csv`` keep the whole
evidence. Not a claim but a limitation the paper states: the method needs
manifold meshes (:data:`LIMITATION`).
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from anseg.configs import departures
from anseg.study import figure_effects, reference, revisions, selection
from anseg.study.effects import (
    DEPENDS,
    DRAWS,
    NOT_REPRODUCED,
    REPRODUCED,
    SEED,
    TIED,
    UNTESTED,
    Effect,
    MissingResult,
    across_readings,
    combined,
    effect,
)
from anseg.study.plan import PLAIN_READING, papers_method_file

RULE = (f"One rule decides every row: the claim becomes a paired effect in its favour (positive = what the paper says), "
        f"per (category, split) or per test mesh; its mean and 95 % percentile bootstrap interval ({DRAWS:,} draws, "
        f"seed {SEED}; over (category, split) two-stage: categories resampled, then splits inside each) give "
        f"**{REPRODUCED}** when the interval lies above 0, **{NOT_REPRODUCED}** when it lies below 0, **{TIED}** when it "
        f"holds 0 or rests on one unit; a claim of several parts is reproduced when every part is, not reproduced when "
        f"any part is. The ablation rows are read two ways, each by this rule: literally (`{PLAIN_READING}`, the "
        f"paper's method as written) and at our strongest (the default), each with its PSB split-0 accuracy; the row "
        f"reads their verdict where both agree, **{DEPENDS}** where they differ. **{UNTESTED}**: no run of ours "
        f"measures it (the row says why). In brackets: the 95 % interval. **Selection**: the share of a row's test "
        f"meshes of PSB splits 1-4 that are split 0's training meshes, on which the default's settings were chosen "
        f"(split 0 is the clean test). Each row in short; the whole evidence (revisions and their drift, between "
        f"revisions and machines; rivals; units) is in the claims_ledger notebook and results/claims_ledger.csv.")
LIMITATION = ("Not a claim but a limitation the paper states: the method needs manifold meshes. So does this code "
              "(anseg.load_mesh refuses others; anseg.repair cuts non-manifold edges and vertices apart first).")


@dataclass(frozen=True)
class Verdict:
    """Our reading of one claim: the evidence in words (numbers from the results), the verdict, the named
    configurations it read where the claim's notebooks' records do not say it (``reads``), and the evidence in
    short for the README (``brief``, about 60 words; "" where the evidence is that short)."""

    evidence: str
    verdict: str
    reads: tuple[str, ...] | None = None
    brief: str = ""


@dataclass(frozen=True)
class Claim:
    name: str
    paper: str  # what the paper claims, in our words
    decide: Callable[[Path], Verdict]  # from the folder that holds results/*.csv
    sources: tuple[str, ...] = ()  # the notebooks whose results decide it (their records name the configuration)
    also_reads: tuple[str, ...] = ()  # configurations it reads beside its notebooks' own (the paper's, in a column)


def _judged(evidence: str, *effects: Effect, reads: tuple[str, ...] | None = None, brief: str = "") -> Verdict:
    return Verdict(evidence, combined(*effects), reads, brief)


def _short(found: Effect, named: bool = True) -> str:
    """An effect in few words: its name (where ``named``), its mean and 95 % interval."""
    interval = "one unit" if len(found.values) < 2 else f"[{found.low:+.2f}, {found.high:+.2f}]"
    return f"{found.name + ' ' if named else ''}{found.mean:+.2f} {interval}"


def _selected(*effects: Effect, brief: bool = False) -> str:
    """"; " and :func:`anseg.study.selection.note` (``brief``: its three words) over the (category, split) units of
    PSB effects, else ""."""
    units = {unit for e in effects if e.values.index.nlevels == 2 for unit in e.values.index}
    note = (selection.brief if brief else selection.note)(units)
    return f"; {note}" if note else ""


def _csv(results: Path, name: str, **options):
    import pandas as pd

    path = results / name
    if not path.is_file():
        raise MissingResult(f"{name} is not written yet")
    return pd.read_csv(path, **options)


def _revisions(runs, arm: str, results: Path) -> str:
    """"; " and :func:`anseg.study.revisions.mix`'s sentence where the arms read other revisions, else ""."""
    sentence = revisions.mix(runs, arm, results)
    return f"; {sentence}" if sentence else ""


def _mixed(runs, arm: str, results: Path) -> str:
    """The README row's note where the arms read several code revisions (the evidence in full names them), else ""."""
    return "mixed code revisions" if revisions.mix(runs, arm, results) else ""


def _psb_runs(results: Path):
    return figure_effects.by_unit(_csv(results, "table1_psb_runs.csv"))


def _psb_accuracy(results: Path) -> Verdict:
    """Ours minus the paper's Table I number of the same category, per (category, split)."""
    ours = _psb_runs(results)
    paper = reference.TABLE_I["methods"]["Ours (paper)"]
    gap = effect(ours - ours.index.get_level_values("category").map(paper).to_numpy(), "ours − the paper")
    split0 = f"split 0, the clean test, {ours.xs(0, level='split').mean():.2f}; " if 0 in ours.index.unique("split") else ""
    evidence = (f"{gap}; ours {ours.groupby(level='category').mean().mean():.2f} against the paper's "
                f"{reference.TABLE_I['average']['Ours (paper)']:.2f} (mean over categories; {split0.rstrip('; ')})"
                + _selected(gap))
    brief = (f"{_short(gap)} over {gap.units}; {split0}the paper {reference.TABLE_I['average']['Ours (paper)']:.2f}"
             + _selected(gap, brief=True))
    try:
        table = _csv(results, "table1_psb.csv", index_col=0)
        plain = next((c for c in table.columns if c.startswith(f"{PLAIN_READING} configuration")), None)
        if plain is not None and table[plain].drop("mean").notna().all():  # the method as written, every category run
            evidence += f"; the paper's method as written ({plain}), not judged: {table.loc['mean', plain]:.2f}"
    except MissingResult:
        pass
    return _judged(evidence, gap, brief=brief)


def _psb_best_in_most(results: Path) -> Verdict:
    """Ours minus the best of Table I's peers in the same category, per (category, split)."""
    import pandas as pd

    ours = _psb_runs(results)
    methods = reference.TABLE_I["methods"]
    peers = [m for m in methods if m != "Ours (paper)"]
    best = pd.DataFrame({p: methods[p] for p in peers}).max(axis=1)
    lead = effect(ours - ours.index.get_level_values("category").map(best).to_numpy(), "ours − the best peer")
    means = ours.groupby(level="category").mean()
    splits = sorted(ours.index.get_level_values("split").unique())
    paper = pd.Series(methods["Ours (paper)"]) - best
    evidence = (f"{lead} (splits {', '.join(map(str, splits))}; peers {', '.join(peers)}, Table I); ours above the best "
                f"peer in {(means > best[means.index]).sum()} of {len(means)} categories (mean over splits); paper "
                f"{paper.mean():+.2f}, above it in {(paper > 0).sum()} of {len(paper)}" + _selected(lead))
    brief = (f"{_short(lead)} over {lead.units}; above it in {(means > best[means.index]).sum()} of {len(means)} "
             f"categories (the paper: {(paper > 0).sum()})" + _selected(lead, brief=True))
    return _judged(evidence, lead, brief=brief)


COSEG_METRIC = "ours, faces"  # COSEG's "ours" wherever the README shows it: the share of faces, as its peers report


def _coseg_small(results: Path) -> Verdict:
    """The paper's sets are the 8 small COSEG sets, which this project does not have; the large sets are shown instead."""
    table = _csv(results, "table2_coseg.csv", index_col=0)
    ours = ", ".join(f"{s.removeprefix('coseg_')} {v:.2f}" for s, v in table[COSEG_METRIC].items())
    paper = reference.TABLE_II["average"]["Ours (paper)"]
    return Verdict(f"the paper's small COSEG sets are not ours: paper {paper:.2f} on them; ours on MeshCNN's large sets "
                   f"(another data set), share of faces (as the peers on those sets), not judged: {ours}",
                   UNTESTED)


def _table3_run_path(results: Path) -> Path | None:
    """Where the stored run behind Table III is: ``results/runs/<key>.json``, the key from the notebook's record
    (its parameters) and the plan, as the notebook found it; None where the record cannot give it."""
    from anseg.study import plan

    record = results / "table3_human.json"
    if not record.is_file():
        return None
    try:
        parameters = plan.resolve_categories(json.loads(record.read_text())["parameters"])
        (run,) = plan.notebook_runs("table3_human.ipynb", parameters)
        experiment, options = plan.planned_experiment(run, parameters)
    except (KeyError, ValueError, TypeError):
        return None
    return results / "runs" / f"{experiment.key(options)}.json"


def _human(results: Path) -> Verdict:
    """Ours minus the paper's 93.12, per test mesh of the stored run (the same 381 / 18 split, MeshCNN's simplified meshes).

    Where the run's per-mesh numbers cannot be reached, the table's single
    number is the one unit (no interval: not distinguishable), and it says so.
    """
    import pandas as pd

    table = _csv(results, "table3_human.csv")
    ours = table[(table.method == "ours") & table.metric.str.startswith("Eq. 5, unit area")].accuracy.iloc[0]
    raw = table[(table.method == "ours") & (table.metric == "Eq. 5, raw area")].accuracy
    paper = reference.TABLE_III["methods"]["Ours (paper)"]
    path = _table3_run_path(results)
    run = json.loads(path.read_text()) if path is not None and path.is_file() else None
    if run is not None and abs(100 * run["accuracy"]["unit_area"] - ours) < 0.01:  # the run the table shows
        per_mesh = pd.Series({m["name"]: 100 * m["accuracy"] for m in run["per_mesh"]}).rename_axis("mesh")
        where = f"run {run['key']}, {run['n_train']} training / {run['n_test']} test meshes"
    else:
        per_mesh = pd.Series({"the table's number": ours}).rename_axis("mesh")
        where = "per-mesh numbers not reachable (no stored run matching results/table3_human.csv): the single number"
    gap = effect(per_mesh - paper, "ours − the paper")
    raw = f" (raw area {raw.iloc[0]:.2f})" if len(raw) else ""
    return _judged(f"{gap}; ours {ours:.2f} unit area{raw} against the paper's {paper:.2f} ({where}); the paper's split, "
                   "on MeshCNN's simplified meshes (about 1,500 faces a mesh): the paper does not say which version "
                   "it used", gap,
                   brief=f"{_short(gap)} over {gap.units}; ours {ours:.2f} unit area{raw} against {paper:.2f}; the "
                         "paper's split, on MeshCNN's simplified meshes (the paper does not say it used them)")


def _readings(results: Path, own: str) -> tuple[str, str]:
    """The two readings' names for a row: literal (``paper``) and strongest (``own``, the notebook's), each with its
    PSB split-0 accuracy from Table I (ours, or the column of a configuration kept for the record), the strongest
    with the paper's beside it (where Table I has them)."""
    literal, strongest = f"literal (`{PLAIN_READING}`", f"strongest ({own}"  # with the accuracies the rule names
    try:
        mean = _csv(results, "table1_psb.csv", index_col=0).loc["mean"]
    except MissingResult:
        return literal + ")", strongest + ")"
    plain = next((c for c in mean.index if c.startswith(f"{PLAIN_READING} configuration, unit area (split 0")), None)
    if plain is not None and np.isfinite(mean[plain]):
        literal += f", {mean[plain]:.2f}"
    column = "ours, unit area (split 0" if own in ("default", "ours") else f"{own} (for the record), unit area (split 0"
    ours = next((c for c in mean.index if c.startswith(column)), None)
    if ours is not None:
        strongest += f", {mean[ours]:.2f}; paper {reference.TABLE_I['average']['Ours (paper)']:.2f}"
    return literal + ")", strongest + ")"


@dataclass(frozen=True)
class Reading:
    """One reading of an ablation claim: its effects (the parts), the evidence in full, and a note for the README's
    row ("" where none: that its arms read several code revisions, which the evidence in full names)."""

    effects: tuple[Effect, ...]
    detail: str
    note: str = ""

    @property
    def verdict(self) -> str:
        return combined(*self.effects)

    def short(self, named: bool) -> str:
        return "; ".join(_short(e, named) for e in self.effects) + f" ({self.verdict})"


def _both_readings(results: Path, own: str | None, literal: Reading, strongest: Reading, says: str) -> Verdict:
    """The row of a claim read two ways: each reading's verdict by the rule, the row's by
    :func:`~anseg.study.effects.across_readings`; ``says`` is what the paper gives to compare with."""
    first, second = _readings(results, own or "ours")
    effects = literal.effects + strongest.effects
    notes = "".join(f"; {note}" for note in dict.fromkeys(r.note for r in (literal, strongest)) if note)
    return Verdict(f"{first}: {literal.detail} ({literal.verdict}); {second}: {strongest.detail} ({strongest.verdict}); "
                   f"{says}{_selected(*effects)}",
                   across_readings(literal.verdict, strongest.verdict), _paper_judged(own),
                   f"{first}: {literal.short(True)}; {second}: {strongest.short(False)}; {says}"
                   f"{_selected(*effects, brief=True)}{notes}")


def _two_readings(results: Path, name: str, source: str, read, says: str) -> Verdict:
    """An ablation claim read on the runs of the paper's method as written and on the notebook's own (the default).

    ``read(runs)`` gives the :class:`Reading` of one table of runs. Until all
    of the ``paper`` configuration's runs are stored the claim is not tested
    (part of them must not stand for all; the notebook says how many). Where
    the notebook runs the ``paper`` configuration itself, that is the one
    reading there is, and the row says so.
    """
    own = _record_configuration(results, source)
    own_runs = _csv(results, name)
    ours = read(own_runs)
    if own == PLAIN_READING:
        first, _ = _readings(results, own)
        return Verdict(f"{first} alone: {ours.detail}; {says}", ours.verdict, (own,),
                       f"{first} alone: {ours.short(True)}; {says}{_selected(*ours.effects, brief=True)}")
    try:
        literal_runs = _csv(results, papers_method_file(name))
    except MissingResult:
        _, second = _readings(results, own or "ours")
        return Verdict(f"the paper's method as written ({PLAIN_READING} configuration) not all run here yet; {second}, "
                       f"not judged alone: {ours.detail}", UNTESTED, (own,) if own else ())
    found = _both_readings(results, own, read(literal_runs), ours, says)
    machines = revisions.cpus([("the default", own_runs), (f"`{PLAIN_READING}`", literal_runs)], results)
    return replace(found, evidence=found.evidence + ("." + machines if machines else ""))


ORDER = (("nonuniform", "uniform"), ("uniform", "none"))  # Table IV's claim, two parts


def _order_reading(results: Path):
    """The :class:`Reading` of a table of Table IV's runs: each part of :data:`ORDER` paired per (category, split)."""
    def read(runs) -> Reading:
        parts = tuple(figure_effects.paired_over_splits(runs, better, worse) for better, worse in ORDER)
        return Reading(parts, "; ".join(map(str, parts)) + _revisions(runs, "mode", results),
                       _mixed(runs, "mode", results))
    return read


def _papers_order() -> str:
    """The paper's two differences (its Table IV, the mean over its three categories)."""
    modes = reference.TABLE_IV["modes"]
    return ", ".join(f"{np.mean([modes[b][c] - modes[w][c] for c in modes[b]]):+.2f}" for b, w in ORDER)


def _ablation_order(results: Path) -> Verdict:
    """Table IV's orderings, two parts: nonuniform − uniform and uniform − none, per (category, split), both readings.

    The paper's differences (its Table IV, mean over its categories) are
    shown beside ours, and where the validation reports exist, the same
    controls on held-out training meshes (not judged).
    """
    verdict = _two_readings(results, "table4_ablation_runs.csv", "table4_ablation", _order_reading(results),
                            f"paper {_papers_order()}")
    try:
        paired = _csv(results / "validation", "confirm2-controls-suite_paired.csv")
        held_out = "; held out, against nonuniform, the default, not judged: " + ", ".join(
            f"{r.arm} {r.mean:+.2f} [{r.low:+.2f}, {r.high:+.2f}] ({r.cells} cells)" for r in paired.itertuples())
        verdict = Verdict(verdict.evidence + held_out, verdict.verdict, verdict.reads, verdict.brief)
    except MissingResult:
        pass
    return verdict


def _order_everywhere(results: Path) -> Verdict:
    """Table IV's orderings on split 0 of every PSB category (the clean test, one unit per category), both readings,
    beside the paper's three categories."""
    if not (results / "table4_every_category_runs.csv").is_file():
        raise MissingResult("split 0 of every PSB category is not run yet (table4_ablation with every_category)")
    return _two_readings(results, "table4_every_category_runs.csv", "table4_ablation", _order_reading(results),
                         f"paper, on its 3 categories, {_papers_order()}")


def _fig4_test_meshes(results: Path):
    meshes = _csv(results, "fig4_test_meshes.csv")
    if PLAIN_READING not in set(meshes.model):
        raise MissingResult("fig4_test_meshes.csv holds no run of the paper's configuration")
    return meshes


def _attention_at_junctions(results: Path) -> Verdict:
    """Attention marks faces near label boundaries, read two ways: the ``paper`` configuration's model (attention
    trained by the class loss alone) and ours (trained towards boundaries as well, so it marks them by construction).

    Per test mesh: its AUC minus 0.5 on the coarse levels of the nonuniform
    hierarchy (:func:`fig4_effects`).
    """
    meshes = _fig4_test_meshes(results)
    literal, ours = figure_effects.fig4_effects(meshes, PLAIN_READING)[0], figure_effects.fig4_effects(meshes, "ours")[0]
    return _both_readings(results, _record_configuration(results, "fig4_attention"),
                          Reading((literal,), f"{literal}, attention trained by the class loss alone"),
                          Reading((ours,), f"{ours}, attention trained towards boundaries too, so by construction"),
                          "the paper gives no number")


def _labels_survive(results: Path) -> Verdict:
    """The nonuniform hierarchy keeps labels through the collapses and the vote better than the uniform one, read
    with the ``paper`` configuration's model and with ours.

    Per test mesh: the share of the area whose true label survives the
    coarsest level and back (the best any coarse labelling can do),
    nonuniform minus uniform (:func:`fig4_effects`).
    """
    meshes = _fig4_test_meshes(results)
    literal, ours = figure_effects.fig4_effects(meshes, PLAIN_READING)[1], figure_effects.fig4_effects(meshes, "ours")[1]
    level = f"labels kept at level {meshes.level.max()} and back"
    return _both_readings(results, _record_configuration(results, "fig4_attention"),
                          Reading((literal,), f"{level}: {literal}"), Reading((ours,), f"{level}: {ours}"),
                          "the paper gives no number")


def _cycles(results: Path) -> Verdict:
    """Accuracy at the paper's N = 4 minus at N = 1, per (category, split), the mean over the shares removed.

    The paper's claim is a rise, then a plateau or a fall; the rise is what
    a difference can test (the paper's N against the first), at a fixed N so
    that no peak is picked on the numbers it is scored on.
    """
    def read(runs) -> Reading:
        units = figure_effects.fig11_units(runs)
        rise = figure_effects.pooled({c: u[1] for c, u in units.items()}, f"N = {reference.FIG11_CHOICE['cycles']} − N = 1")
        shares = "; ".join(f"{c} {', '.join(f'{r:g}' for r in u[0].index.unique('removed'))}" for c, u in units.items())
        arms = runs.astype({"cycles": str})
        return Reading((rise,), f"{rise} (shares removed: {shares}){_revisions(arms, 'cycles', results)}",
                       _mixed(arms, "cycles", results))

    return _two_readings(results, "fig11_cycles_ratio.csv", "fig11_cycles_ratio", read,
                         "the paper gives curves, no numbers")


def _best_setting(results: Path) -> Verdict:
    """The paper's point (N = 4, removing 0.5) minus the best other point of the category's grid, per (category, split).

    Each split's rival is picked by its mean over the other splits
    (:func:`anseg.study.figure_effects.cross_fitted_rivals`): picked on the
    runs it is scored on, it would be favoured (the winner's curse), and a
    loss of the paper's choice overstated.
    """
    def read(runs) -> Reading:
        units = figure_effects.fig11_units(runs)
        gap = figure_effects.pooled({c: u[2] for c, u in units.items()}, "the paper's point − the best other")
        rivals = "; ".join(f"{c} {figure_effects.describe_rivals(u[3])} (of {len(u[0])} points)" if u[3] is not None
                           else f"{c}: the paper's choice not run, or one split" for c, u in units.items())
        grid = runs.assign(point=runs.removed.astype(str) + "/" + runs.cycles.astype(str))
        return Reading((gap,), f"{gap} (best other point, picked on the other splits: {rivals})"
                               f"{_revisions(grid, 'point', results)}",
                       _mixed(grid, "point", results))

    return _two_readings(results, "fig11_cycles_ratio.csv", "fig11_cycles_ratio", read,
                         "each split's rival picked on the other splits")


def _features(results: Path) -> Verdict:
    """Two parts: the full set beats the best other set, and adding AGD helps (:func:`feature_effects`).

    Where the best other set is the set without AGD in every category, the
    two parts are one number, and the row says it once (both still judged).
    """
    def read(runs) -> Reading:
        best, agd = figure_effects.feature_effects(runs)
        if best.values.equals(agd.values):  # the best other set is edge+gc+sdf everywhere: one number (one verdict)
            once = Effect(f"{agd.name} (the best other set)", agd.values, agd.mean, agd.low, agd.high)
            return Reading((once,), str(once) + _revisions(runs, "features", results),
                           _mixed(runs, "features", results))
        return Reading((best, agd), f"{best}; {agd}{_revisions(runs, 'features', results)}",
                       _mixed(runs, "features", results))

    return _two_readings(results, "fig12_features.csv", "fig12_features", read, "the paper gives renders, no numbers")


def _better_than_meshcnn(results: Path) -> Verdict:
    """No MeshCNN or Guo et al. run here, and the paper's evidence (Fig. 9) is two renders."""
    return Verdict("no run of MeshCNN or of Guo et al. here, and the paper's evidence is visual (Fig. 9, two meshes); "
                   "the MeshCNN numbers of Table I are the paper's, not measured by us", UNTESTED)


# benchmarks/segment.py --json: one mesh segmented end to end, its descriptors and eigenbasis computed, nothing cached
END_TO_END = Path("benchmarks") / "segment_end_to_end.json"


def _cost(results: Path) -> Verdict:
    """Our training and evaluation times, with their machines: not comparable (other hardware), so not judged.

    The evaluation the paper times includes computing the descriptors; ours
    is given both ways: per test mesh from the cache (Table I's runs) and end
    to end on one mesh of the paper's size (:data:`END_TO_END`, when stored).
    """
    table = _csv(results, "table1_psb_runs.csv")
    by_machine = table.groupby("trained_on")
    training = by_machine.train_seconds.median() / 60
    evaluation = by_machine.evaluate_seconds_per_mesh.median()
    end_to_end = ""
    if (path := results / END_TO_END).is_file():
        stored = json.loads(path.read_text())
        ours, machine = stored["ours"], stored["environment"]
        device = machine["cuda"] or f"CPU, {machine['cpus']} cores"
        stages = ours["stages"]
        end_to_end = (f"; end to end, descriptors and eigenbasis computed: {stages['total']:.1f} s for {ours['mesh']} "
                      f"({ours['faces']} faces) on {device}, of which descriptors {stages['features (level 0)']:.1f} s"
                      + (f" and the network's eigenbasis {stages['spectrum']:.1f} s" if "spectrum" in stages else "")
                      + f" (revision {machine['code_revision'][:7]}, results/{END_TO_END.as_posix()})")
    brief = ("other hardware (the paper: an RTX 3090); ours, not judged, per PSB model: training "
             + ", ".join(f"{m:.1f} min on {machine}" for machine, m in training.items())
             + "; per test mesh: evaluation " + ", ".join(f"{s:.2f} s" for s in evaluation) + " with descriptors "
             "cached" + (f", {stages['total']:.1f} s end to end ({ours['faces']} faces)" if end_to_end else ""))
    return Verdict("other hardware (the paper: an RTX 3090); the paper's 30 s include computing the descriptors; "
                   "ours, not judged: median training per PSB model "
                   + ", ".join(f"{m:.1f} min on {machine}" for machine, m in training.items())
                   + "; median evaluation per test mesh, descriptors cached, "
                   + ", ".join(f"{s:.2f} s on {machine}" for machine, s in evaluation.items()) + end_to_end, UNTESTED,
                   brief=brief)


CLAIMS = [
    Claim("PSB accuracy", "95.29 mean over 16 PSB categories (Table I)", _psb_accuracy, ("table1_psb",), (PLAIN_READING,)),
    Claim("PSB, best in most categories", "above ShapePFCN, MeshCNN and MeshWalker in most categories", _psb_best_in_most,
          ("table1_psb",)),
    Claim("COSEG accuracy", "93.55 mean over the 8 small COSEG sets (Table II)", _coseg_small, ("table2_coseg",)),
    Claim("Human body accuracy", "93.12 on the human body set, 381 training / 18 test models (Table III)", _human,
          ("table3_human",)),
    Claim("Downsampling order", "nonuniform > uniform > none (Table IV)", _ablation_order, ("table4_ablation",)),
    Claim("Order, every category", "nonuniform > uniform > none (Table IV, on 3 categories)", _order_everywhere,
          ("table4_ablation",)),
    Claim("Attention at junctions", "attention concentrates at details and part junctions (Fig. 4)", _attention_at_junctions,
          ("fig4_attention",), (PLAIN_READING,)),
    Claim("More cycles help", "accuracy rises with N, then levels off or falls (Fig. 11)", _cycles, ("fig11_cycles_ratio",)),
    Claim("N = 4, ratio 0.5", "4 cycles removing half the faces each is the best choice (Fig. 11)", _best_setting,
          ("fig11_cycles_ratio",)),
    Claim("All four feature groups", "edge + GC + SDF + AGD is the best set; AGD adds global information (Fig. 12)", _features,
          ("fig12_features",)),
    Claim("Better than MeshCNN and Guo et al.", "visibly better than MeshCNN and Guo et al. (Fig. 9)", _better_than_meshcnn),
    Claim("Labels survive", "labels survive the collapses and the vote back to the input faces, better than with other "
          "downsampling (Sec. III-C)", _labels_survive, ("fig4_attention",), (PLAIN_READING,)),
    Claim("Cost", "10 minutes of training and 30 s of evaluation per model of 20K-30K faces", _cost, ("table1_psb",)),
]


def _record_configuration(results: Path, source: str) -> str | None:
    """The configuration a notebook's record names ("not recorded" for a record from before; None when there is none)."""
    record = results / f"{source}.json"
    return (json.loads(record.read_text()).get("configuration") or "not recorded") if record.is_file() else None


def _paper_judged(own: str | None) -> tuple[str, ...]:
    """A row read two ways names the paper's configuration (the literal reading) first, then the notebook's own."""
    return (PLAIN_READING,) + ((own,) if own and own != PLAIN_READING else ())


def _configurations(results: Path, sources: tuple[str, ...], also_reads: tuple[str, ...] = ()) -> str:
    """The named configurations of the runs behind a claim, from its notebooks' records ("" when none is read)."""
    names = []
    for source in sources:
        name = _record_configuration(results, source)
        if name is not None and name not in names:
            names.append(name)
    return ", ".join(names + [name for name in also_reads if names and name not in names])


def ledger(results: str | Path, benchmark: bool = True):
    """The ledger as a DataFrame (claim, the paper, in short, our evidence, configuration, verdict) from the folder of
    results/*.csv: ``in short`` for the README, ``our evidence`` whole.

    ``benchmark=False`` (results of the synthetic data): no claim of the
    paper can be judged on them, and every row says so.
    """
    import pandas as pd

    rows = []
    for claim in CLAIMS:
        try:
            if not benchmark:
                raise MissingResult("these results come from synthetic data, not the paper's benchmarks")
            verdict = claim.decide(Path(results))
        except MissingResult as missing:
            verdict = Verdict(f"no result: {missing}", UNTESTED)
        rows.append({"claim": claim.name, "the paper": claim.paper, "in short": verdict.brief or verdict.evidence,
                     "our evidence": verdict.evidence,
                     "configuration": ("" if not benchmark else ", ".join(verdict.reads) if verdict.reads is not None
                                       else _configurations(Path(results), claim.sources, claim.also_reads)),
                     "verdict": verdict.verdict})
    return pd.DataFrame(rows)


def _value(value) -> str:
    return " + ".join(value) if isinstance(value, tuple) else str(value)


def markdown(table, evidence: str = "in short") -> str:
    """The ledger as Markdown: the rule, the limitation, what the default changes from the paper's method, then the
    table with the evidence of column ``evidence`` (the README's rows in short; the notebook's whole)."""
    lines = [RULE, "", LIMITATION, "", f"What the default changes from the paper's method as written (`{PLAIN_READING}`): "
             "the two readings of the ablation rows differ in these settings:", "",
             "| setting | the paper's method | default | what it sets |", "|---|---|---|---|"]
    lines += [f"| `{name}` | {_value(paper)} | {_value(ours)} | {what} |" for name, paper, ours, what in departures()]
    lines += ["", "| claim | the paper | our evidence | configuration | verdict |", "|---|---|---|---|---|"]
    lines += [f"| {r['claim']} | {r['the paper']} | {r[evidence]} | {r['configuration']} | **{r['verdict']}** |"
              for _, r in table.iterrows()]
    return "\n".join(lines)
