"""The claims ledger: every claim of the paper, our verdict and the evidence that decides it, read from ``results/``.

One row per claim: what the paper says, what our stored results say, and a
verdict, ``holds``, ``does not hold`` or ``cannot be tested here``, with the
reason. Nothing is typed in: every number comes from the result files the
notebooks write (``results/*.csv``) and the validation reports
(``results/validation/*.csv``), so the ledger changes when they do. A file
that is missing makes its claim ``cannot be tested here`` and says which.

How a verdict is reached, per claim, is in the function that decides it.
Differences are read against their spread where the results have one (the
standard deviation over splits, a bootstrap interval over held-out cells);
a difference inside it is not called a finding either way.
"""

from __future__ import annotations

import statistics
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from anseg.study import reference
from anseg.study.plan import PLAIN_READING

HOLDS, FAILS, UNTESTED = "holds", "does not hold", "cannot be tested here"
SIGN_ALONE = " (one split: no spread, the sign decides)"  # how a paired difference of one split is read


@dataclass(frozen=True)
class Verdict:
    """Our reading of one claim: the evidence in words (numbers from the results) and the verdict."""

    evidence: str
    verdict: str


@dataclass(frozen=True)
class Claim:
    name: str
    paper: str  # what the paper claims, in our words
    decide: Callable[[Path], Verdict]  # from the folder that holds results/*.csv
    sources: tuple[str, ...] = ()  # the notebooks whose results decide it (their records name the configuration)
    also_reads: tuple[str, ...] = ()  # configurations it reads beside its notebooks' own (the paper's, in a column)


class MissingResult(Exception):
    """A result file a claim needs is not there."""


def _csv(results: Path, name: str, **options):
    import pandas as pd

    path = results / name
    if not path.is_file():
        raise MissingResult(f"{name} is not written yet")
    return pd.read_csv(path, **options)


def _psb_mean(results: Path) -> Verdict:
    """Holds when our mean over the splits reaches the paper's, or falls short by less than its split-to-split spread."""
    table = _csv(results, "table1_psb.csv", index_col=0)
    over = next(c for c in table.columns if c.startswith("ours, unit area, mean of"))
    splits = over.split("mean of ")[1].split()[0]
    ours, spread = table.loc["mean", over], table.loc["mean", "ours, std over splits"]
    paper = reference.TABLE_I["average"]["Ours (paper)"]
    short = paper - ours
    spread_text = f" ± {spread:.2f} (std over splits)" if int(splits) > 1 else " (one split: no spread)"
    evidence = f"ours {ours:.2f}{spread_text}, {splits} split(s), against the paper's {paper:.2f}"
    plain = next((c for c in table.columns if c.startswith(f"{PLAIN_READING} configuration")), None)
    if plain is not None and table[plain].drop("mean").notna().all():  # the method as written, where every category ran
        evidence += f"; the paper's method as written ({plain}): {table.loc['mean', plain]:.2f}"
    return Verdict(evidence, HOLDS if short <= (spread if int(splits) > 1 else 0.0) else FAILS)


def _psb_best_in_most(results: Path) -> Verdict:
    """Our split-0 accuracy against every peer of Table I, per category: holds when ours is the best in more than half."""
    table = _csv(results, "table1_psb.csv", index_col=0).drop(index="mean")
    ours = table[next(c for c in table.columns if c.startswith("ours, unit area (split"))]
    peers = [m for m in reference.TABLE_I["methods"] if m != "Ours (paper)"]
    best = [c for c in ours.index if all(ours[c] > reference.TABLE_I["methods"][p][c] for p in peers)]
    evidence = (f"ours (split 0) beats {', '.join(peers)} in {len(best)} of {len(ours)} categories"
                + (f" ({', '.join(best)})" if best else ""))
    return Verdict(evidence, HOLDS if len(best) > len(ours) / 2 else FAILS)


def _coseg_small(results: Path) -> Verdict:
    """The paper's sets are the 8 small COSEG sets, which this project does not have; the large sets are shown instead."""
    table = _csv(results, "table2_coseg.csv", index_col=0)
    ours = ", ".join(f"{s} {v:.2f}" for s, v in table["ours, unit area"].items())
    paper = reference.TABLE_II["average"]["Ours (paper)"]
    return Verdict(f"paper {paper:.2f} on the small sets; ours on MeshCNN's large sets (another data set): {ours}",
                   UNTESTED)


def _human(results: Path) -> Verdict:
    """The paper's full-resolution human set is not ours (MeshCNN's simplified version), so the numbers do not compare."""
    table = _csv(results, "table3_human.csv")
    ours = table[(table.method == "ours") & table.metric.str.startswith("Eq. 5, unit area")].accuracy.iloc[0]
    paper = reference.TABLE_III["methods"]["Ours (paper)"]
    return Verdict(f"paper {paper:.2f} on the full-resolution set; ours {ours:.2f} on MeshCNN's simplified version",
                   UNTESTED)


@dataclass(frozen=True)
class PairedDifference:
    """Table IV's row ``better`` minus ``worse``, paired: per split, the mean over categories of the difference.

    Paired, so that a split's own difficulty cancels. ``reading``: ``holds``
    when the mean over splits exceeds one standard deviation over splits,
    ``does not hold`` when it falls below minus one, ``within the spread``
    otherwise (a single split has no spread: its sign decides).
    """

    better: str
    worse: str
    per_split: tuple[float, ...]

    @property
    def mean(self) -> float:
        return statistics.fmean(self.per_split)

    @property
    def std(self) -> float:
        return statistics.stdev(self.per_split) if len(self.per_split) > 1 else float("nan")

    @property
    def reading(self) -> str:
        margin = self.std if len(self.per_split) > 1 else 0.0
        return HOLDS if self.mean > margin else FAILS if self.mean < -margin else "within the spread"

    def __str__(self) -> str:
        spread = f" ± {self.std:.2f}" if len(self.per_split) > 1 else ""
        return f"{self.better} − {self.worse} {self.mean:+.2f}{spread} over {len(self.per_split)} split(s)"


def paired_over_splits(runs, better: str, worse: str) -> PairedDifference:
    """The paired difference of two Table IV rows from its runs
    (``table4_ablation_runs.csv``: category, split, mode, unit_area)."""
    per_split = runs.pivot_table(index=["category", "split"], columns="mode", values="unit_area")
    by_split = (per_split[better] - per_split[worse]).groupby("split").mean()
    return PairedDifference(better, worse, tuple(float(d) for d in by_split))


def _ablation_order(results: Path) -> Verdict:
    """Table IV's orderings on the test splits, paired over splits, and the same controls on held-out training meshes.

    Holds when nonuniform beats uniform and uniform beats the paper's "none",
    each by more than its spread over splits (:class:`PairedDifference`); the
    held-out interval is given beside it.
    """
    runs = _csv(results, "table4_ablation_runs.csv")
    means = runs.groupby("mode").unit_area.mean()
    differences = [paired_over_splits(runs, "nonuniform", "uniform"), paired_over_splits(runs, "uniform", "none")]
    evidence = (f"Table IV, mean of {', '.join(runs.category.unique())} over {len(differences[0].per_split)} split(s): "
                + ", ".join(f"{row} {means[row]:.2f}" for row in ("nonuniform", "uniform", "none") if row in means)
                + "; paired: " + ", ".join(f"{d} ({d.reading})" for d in differences))
    try:
        paired = _csv(results / "validation", "confirm2-controls-suite_paired.csv")
        evidence += "; held out, against nonuniform: " + ", ".join(
            f"{r.arm} {r.mean:+.2f} [{r.low:+.2f}, {r.high:+.2f}] ({r.cells} cells)" for r in paired.itertuples())
    except MissingResult:
        pass
    return Verdict(evidence, HOLDS if all(d.reading == HOLDS for d in differences) else FAILS)


def fig4_summary(meshes):
    """From Fig. 4's per-mesh table (``fig4_test_meshes.csv``): the two figures its claims are read by.

    The attention's mean AUC for near-boundary faces over the test meshes,
    by model and level of the nonuniform hierarchies (a Series), and the
    mean share of the area whose true label survives the trip to the
    coarsest level and back, by model and downsampling (a DataFrame).
    """
    auc = meshes[meshes.downsampling == "nonuniform"].groupby(["model", "level"])["attention AUC, near vs elsewhere"].mean()
    coarsest = meshes[meshes.level == meshes.level.max()]
    return auc, coarsest.groupby(["model", "downsampling"])["labels kept (%)"].mean().unstack()


def _fig4_test_meshes(results: Path):
    meshes = _csv(results, "fig4_test_meshes.csv")
    if PLAIN_READING not in set(meshes.model):
        raise MissingResult("fig4_test_meshes.csv holds no run of the paper's configuration")
    return meshes


def _attention_at_junctions(results: Path) -> Verdict:
    """Whether attention trained by the class loss alone (the paper's) marks the faces near label boundaries.

    Read from Fig. 4's test meshes: with the ``paper`` configuration's model,
    the attention's AUC for faces near a boundary against the rest on every
    coarse level of its nonuniform hierarchy, the mean over the test meshes
    (holds when above 0.5 on every level). Our default's attention is trained
    towards boundaries, so it marks them by construction: shown beside it.
    """
    meshes = _fig4_test_meshes(results)
    auc = fig4_summary(meshes)[0].drop(0, level="level")  # level 0 is the input mesh, not a collapse
    evidence = (f"mean AUC of near-boundary faces over {meshes.mesh.nunique()} test meshes, coarse levels of the "
                f"nonuniform hierarchy: the paper's unsupervised attention "
                f"{', '.join(f'{a:.2f}' for a in auc[PLAIN_READING])}; ours (supervised) "
                f"{', '.join(f'{a:.2f}' for a in auc['ours'])}")
    return Verdict(evidence, HOLDS if (auc[PLAIN_READING] > 0.5).all() else FAILS)


@dataclass(frozen=True)
class CyclesReading:
    """Fig. 11 read for one category, each difference paired over the splits (:class:`PairedDifference`).

    ``climbs``: per share removed, the curve's peak (the N of the best mean)
    minus its first N; ``best``: the (share removed, N) of the best mean;
    ``choice_gap``: the best point minus the paper's choice (N = 4, removing
    0.5), None where the grid does not hold it.
    """

    category: str
    means: dict  # (removed, cycles) -> mean accuracy over the splits
    climbs: dict  # removed -> PairedDifference
    best: tuple[float, int]
    choice_gap: PairedDifference | None

    def __str__(self) -> str:
        removed, cycles = self.best
        text = f"**{self.category}**: best N = {cycles}, removing {removed:g} per cycle ({self.means[self.best]:.2f} %)"
        one_split = len(next(iter(self.climbs.values())).per_split) == 1
        beyond = "" if one_split else " by more than the spread"
        note = SIGN_ALONE if one_split else ""
        choice = reference.FIG11_CHOICE
        if self.choice_gap is not None:
            chosen = self.means[(choice["removed"], choice["cycles"])]
            text += (f"; the paper's choice N = {choice['cycles']}, removing {choice['removed']:g}: {chosen:.2f} %, "
                     + (f"below the best point{beyond}{note}: the paper's second statement does not hold here"
                        if self.choice_gap.reading == HOLDS
                        else "the best point or within its spread: the paper's second statement is not contradicted here"))
        climbing = [r for r, d in self.climbs.items() if d.reading == HOLDS]
        return text + (f"; the accuracy climbs from the first N to its peak{beyond} for {len(climbing)} "
                       f"of {len(self.climbs)} shares removed{note} (peaks at N = "
                       + ", ".join(d.better.removeprefix("N = ") for d in self.climbs.values()) + ")")


def fig11_readings(runs) -> list[CyclesReading]:
    """Fig. 11's runs (``fig11_cycles_ratio.csv``: category, split, removed, cycles, unit_area) read per category.

    The Fig. 11 notebook writes its sentences from these, and the ledger its
    two rows, so the figure and the ledger cannot read the grid differently.
    """
    choice = reference.FIG11_CHOICE
    readings = []
    for category, table in runs.groupby("category"):
        accuracy = table.pivot_table(index=["removed", "cycles"], columns="split", values="unit_area")
        means = accuracy.mean(axis=1)
        climbs = {}
        for removed, curve in accuracy.groupby(level="removed"):
            curve = curve.droplevel("removed").sort_index()
            peak, first = curve.mean(axis=1).idxmax(), curve.index[0]
            climbs[removed] = PairedDifference(f"N = {peak}", f"N = {first}",
                                               tuple(map(float, curve.loc[peak] - curve.loc[first])))
        best = means.idxmax()
        key = (choice["removed"], choice["cycles"])
        gap = None
        if key in accuracy.index:
            gap = PairedDifference(f"N = {best[1]}, removing {best[0]:g}", "the paper's choice",
                                   tuple(map(float, accuracy.loc[best] - accuracy.loc[key])))
        readings.append(CyclesReading(category, means.to_dict(), climbs, best, gap))
    return readings


def _fig11(results: Path) -> tuple[list[CyclesReading], int]:
    table = _csv(results, "fig11_cycles_ratio.csv")
    return fig11_readings(table), table["split"].nunique()


def _cycles(results: Path) -> Verdict:
    """Holds when, for most curves (category x share removed), the accuracy climbs from N = 1 to a peak beyond it.

    Climbs: the peak minus N = 1, paired over the splits, exceeds its
    standard deviation over the splits (:class:`PairedDifference`).
    """
    readings, splits = _fig11(results)
    climbs = [d for r in readings for d in r.climbs.values()]
    held = sum(d.reading == HOLDS for d in climbs)
    peaks = "; ".join(f"{r.category} " + ", ".join(f"{removed:g}: {d.better}" for removed, d in r.climbs.items())
                      for r in readings)
    beyond = f" by more than the spread over {splits} splits" if splits > 1 else SIGN_ALONE
    return Verdict(f"{held} of {len(climbs)} curves (category x share removed) climb from N = 1 to their peak{beyond} "
                   f"(peaks by share removed: {peaks})",
                   HOLDS if held > len(climbs) / 2 else FAILS)


def _best_setting(results: Path) -> Verdict:
    """Holds when, in every category, no point of the grid beats the paper's N = 4, removing 0.5, by more than the spread."""
    readings, splits = _fig11(results)
    parts = []
    for r in readings:
        removed, cycles = r.best
        # the grid's range says whether "best" separates anything: a flat grid ties every choice
        part = (f"{r.category}: best N = {cycles}, removing {removed:g} ({r.means[r.best]:.2f}; "
                f"the {len(r.means)} points within {min(r.means.values()):.2f}-{max(r.means.values()):.2f})")
        if r.choice_gap is None:
            part += "; the paper's choice not run"
        else:
            part += f"; {r.choice_gap}" + ("" if splits == 1 else ", beyond the spread" if r.choice_gap.reading == HOLDS
                                           else ", within the spread")
        parts.append(part)
    below = any(r.choice_gap is None or r.choice_gap.reading == HOLDS for r in readings)
    note = SIGN_ALONE if splits == 1 else f" (means over {splits} splits)"
    return Verdict("; ".join(parts) + note, FAILS if below else HOLDS)


def _features(results: Path) -> Verdict:
    """Holds when the four groups together score best in every category and AGD adds at least 2 points on average."""
    from anseg.features import ABLATION_SETS

    table = _csv(results, "fig12_features.csv")
    # the paper's four sets, each the mean over the splits run
    grid = table.groupby(["category", "features"]).unit_area.mean().unstack()[list(ABLATION_SETS)]
    full, without_agd = "edge+gc+sdf+agd", "edge+gc+sdf"
    gain = (grid[full] - grid[without_agd]).mean()
    best = (grid.idxmax(axis=1) == full).sum()
    evidence = (f"all four best in {best} of {len(grid)} categories; AGD adds {gain:+.2f} on average "
                f"({', '.join(f'{c} {v:+.2f}' for c, v in (grid[full] - grid[without_agd]).items())})")
    return Verdict(evidence, HOLDS if best == len(grid) and gain >= 2 else FAILS)


def _better_than_meshcnn(results: Path) -> Verdict:
    """Against MeshCNN's Table I numbers per category (the paper's comparison is visual, Fig. 9); Guo et al. has none here."""
    table = _csv(results, "table1_psb.csv", index_col=0).drop(index="mean")
    ours = table[next(c for c in table.columns if c.startswith("ours, unit area (split"))]
    meshcnn = reference.TABLE_I["methods"]["MeshCNN"]
    wins = sum(ours[c] > meshcnn[c] for c in ours.index)
    return Verdict(f"ours above MeshCNN in {wins} of {len(ours)} PSB categories (split 0); Guo et al. not run here",
                   HOLDS if wins > len(ours) / 2 else FAILS)


def _cost(results: Path) -> Verdict:
    """Training and evaluation time per model from the run records, with their machines.

    Untested: the paper's figures are on an RTX 3090. A run's evaluation
    reads the input descriptors from the feature cache, so its seconds are
    the hierarchy, the network and the graph cut of each test mesh.
    """
    table = _csv(results, "table1_psb_runs.csv")
    by_machine = table.groupby("trained_on")
    training = by_machine.train_seconds.median() / 60
    evaluation = by_machine.evaluate_seconds_per_mesh.median()
    evidence = ("median training per PSB model: " + ", ".join(f"{m:.1f} min on {machine}" for machine, m in training.items())
                + "; median evaluation per test mesh, input descriptors cached: "
                + ", ".join(f"{s:.2f} s on {machine}" for machine, s in evaluation.items()))
    return Verdict(evidence + " (paper: 10 min training, 30 s evaluation, RTX 3090)", UNTESTED)


def _labels_survive(results: Path) -> Verdict:
    """Whether the paper's own hierarchy keeps labels through the collapses and the vote at least as well as uniform.

    Read from Fig. 4's test meshes: their true labels carried to the coarsest
    level and back (the best any coarse labelling can do), the mean over the
    meshes, for the nonuniform hierarchy of the ``paper`` configuration's
    model against the uniform one; ours is shown beside it.
    """
    meshes = _fig4_test_meshes(results)
    kept = fig4_summary(meshes)[1]
    named = {PLAIN_READING: "the paper's configuration (unsupervised attention)", "ours": "ours (supervised attention)"}
    evidence = ("; ".join(f"{named.get(who, who)}: nonuniform {kept.loc[who, 'nonuniform']:.2f} %, "
                          f"uniform {kept.loc[who, 'uniform']:.2f} %" for who in kept.index)
                + f" of the area of {meshes.mesh.nunique()} test meshes keeps its label through the coarsest level and back")
    paper = kept.loc[PLAIN_READING]
    return Verdict(evidence, HOLDS if paper["nonuniform"] >= paper["uniform"] else FAILS)


def _manifold(results: Path) -> Verdict:
    """A property of the code, not of a result: the checks refuse non-manifold meshes, and repair cuts them apart."""
    return Verdict("our features and collapse need manifold meshes too (anseg.load_mesh refuses others); "
                   "anseg.repair cuts non-manifold edges and vertices apart, so such meshes are segmented after repair",
                   HOLDS)


CLAIMS = [
    Claim("PSB accuracy", "95.29 mean over 16 PSB categories (Table I)", _psb_mean, ("table1_psb",), (PLAIN_READING,)),
    Claim("PSB, best in most categories", "above ShapePFCN, MeshCNN and MeshWalker in most categories", _psb_best_in_most,
          ("table1_psb",)),
    Claim("COSEG accuracy", "93.55 mean over the 8 small COSEG sets (Table II)", _coseg_small, ("table2_coseg",)),
    Claim("Human body accuracy", "93.12 on the human body set (Table III)", _human, ("table3_human",)),
    Claim("Downsampling order", "nonuniform > uniform > none (Table IV)", _ablation_order, ("table4_ablation",)),
    Claim("Attention at junctions", "attention concentrates at details and part junctions (Fig. 4)", _attention_at_junctions,
          ("fig4_attention",), (PLAIN_READING,)),
    Claim("More cycles help", "accuracy rises with N, then levels off or falls (Fig. 11)", _cycles, ("fig11_cycles_ratio",)),
    Claim("N = 4, ratio 0.5", "4 cycles removing half the faces each is the best choice (Fig. 11)", _best_setting,
          ("fig11_cycles_ratio",)),
    Claim("All four feature groups", "edge + GC + SDF + AGD is the best set; AGD adds global information (Fig. 12)", _features,
          ("fig12_features",)),
    Claim("Better than MeshCNN and Guo et al.", "visibly better than MeshCNN and Guo et al. (Fig. 9)", _better_than_meshcnn,
          ("table1_psb",)),
    Claim("Labels survive", "labels survive the collapses and the vote back to the input faces, better than with other "
          "downsampling (Sec. III-C)", _labels_survive, ("fig4_attention",), (PLAIN_READING,)),
    Claim("Manifold input", "the method needs manifold meshes (a stated limitation)", _manifold),
    Claim("Cost", "10 minutes of training and 30 s of evaluation per model of 20K-30K faces", _cost, ("table1_psb",)),
]


def _configurations(results: Path, sources: tuple[str, ...], also_reads: tuple[str, ...] = ()) -> str:
    """The named configurations of the runs behind a claim, from its notebooks' records ("" when none is read)."""
    import json

    names = []
    for source in sources:
        record = results / f"{source}.json"
        name = (json.loads(record.read_text()).get("configuration") or "not recorded") if record.is_file() else None
        if name is not None and name not in names:
            names.append(name)
    return ", ".join(names + [name for name in also_reads if names and name not in names])


def ledger(results: str | Path, benchmark: bool = True):
    """The ledger as a DataFrame (claim, the paper, our evidence, configuration, verdict) from the folder of results/*.csv.

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
        rows.append({"claim": claim.name, "the paper": claim.paper, "our evidence": verdict.evidence,
                     "configuration": _configurations(Path(results), claim.sources, claim.also_reads) if benchmark else "",
                     "verdict": verdict.verdict})
    return pd.DataFrame(rows)


def markdown(table) -> str:
    """The ledger as a Markdown table (for the README and the notebook)."""
    lines = ["| claim | the paper | our evidence | configuration | verdict |", "|---|---|---|---|---|"]
    lines += [f"| {r.claim} | {r._2} | {r._3} | {r.configuration} | **{r.verdict}** |" for r in table.itertuples()]
    return "\n".join(lines)
