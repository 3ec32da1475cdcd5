"""README's headline tables and claims ledger, written from the real run's result files (nothing typed by hand)."""

from __future__ import annotations

from pathlib import Path

from anseg.study import figure_effects, ledger, revisions, selection
from anseg.study.plan import PLAIN_READING, TABLE_IV_ROWS, papers_method_file

HEADLINE_START = "<!-- headline: written by `python -m anseg.study.reproduce --data real` from results/*.csv; do not edit -->"
HEADLINE_END = "<!-- /headline -->"
LEDGER_START = "<!-- ledger: written by `python -m anseg.study.reproduce --data real` from results/*.csv; do not edit -->"
LEDGER_END = "<!-- /ledger -->"


def _markdown_row(label, values) -> str:
    """A table row: numbers with two decimals, missing ones (NaN) left empty."""
    import pandas as pd

    return f"| {label} | " + " | ".join("" if pd.isna(v) else f"{v:.2f}" for v in values) + " |"


def headline(results_dir: Path) -> str:
    """README's headline tables, built from the real run's result files (nothing typed by hand)."""
    import pandas as pd

    table1 = pd.read_csv(results_dir / "table1_psb.csv", index_col=0)
    split = next(c for c in table1.columns if c.startswith("ours, unit area (split"))
    over_splits = next(c for c in table1.columns if c.startswith("ours, unit area, mean of"))
    n_splits = int(over_splits.split("mean of ")[1].split()[0])
    more = [over_splits, "ours, std over splits"] if n_splits > 1 else []
    paper = "Ours (paper), Table I"
    peers = [c for c in table1.columns if c.endswith("our data, split 0") and table1[c].notna().any()]
    first = split.split("(")[1].rstrip(")")
    selected = selection.psb_note(table1.index.drop("mean"), range(n_splits)) if more else ""
    lines = [f"PSB, Table I ([notebook](notebooks/executed/table1_psb.ipynb)): Eq. 5 with unit area, "
             f"{first}, graph cut on: the clean figure, tested on meshes no setting was chosen on; beside ours the "
             "paper's column and the peers this project reran on exactly our data (split 0, one seed; "
             + (", ".join(f"{c.removesuffix(', our data, split 0')} on {table1[c].drop('mean').notna().sum()} of "
                          f"{len(table1) - 1} categories" for c in peers) or "none yet")
             + ", the others not run here, `results/peers/`)."
             + (f" Then our mean over {n_splits} splits and its standard deviation (in the mean row: the spread of "
                f"the 16-category mean from split to split); of those splits, {selected}." if more else ""),
             "", "| category | ours | paper | ours − paper | " + " | ".join(c.removesuffix(", our data, split 0") for c in peers)
             + (f" | ours, {n_splits} splits | std" if more else "") + " |",
             "|---|---|---|---|" + "---|" * (len(peers) + len(more))]
    for category, row in table1.iterrows():
        cells = [row[split], row[paper], row[split] - row[paper], *(row[c] for c in peers + more)]
        lines.append(_markdown_row(f"**{category}**" if category == "mean" else category, cells))
    table4 = pd.read_csv(results_dir / "table4_ablation.csv", index_col=0)
    rows = [m for m in TABLE_IV_ROWS if f"ours, {m}" in table4.columns]
    ablation_runs = pd.read_csv(results_dir / "table4_ablation_runs.csv")
    literal_path = results_dir / papers_method_file("table4_ablation_runs.csv")
    literal = pd.read_csv(literal_path) if literal_path.is_file() else None
    ablation_splits = sorted(ablation_runs.split.unique())
    on = "split 0" if ablation_splits == [0] else f"the mean over {len(ablation_splits)} splits"
    selected = selection.psb_note(table4.index, ablation_splits)
    readings = [("default", ablation_runs)] + ([(f"`{PLAIN_READING}`", literal)] if literal is not None else [])
    lines += ["", f"Table IV, downsampling ablation on PSB, {on} ([notebook](notebooks/executed/table4_ablation.ipynb)), "
              "ours (paper); \"none\" is the paper's row, a per-face classifier without attention or downsampling, "
              "and \"none, transformer\" our network on the input mesh alone (no paper number). Each category twice: "
              f"at our strongest (the default) and literally (`{PLAIN_READING}`, the paper's method as written)"
              + (f"; {selected}" if selected else "") + "." + revisions.cpus(readings, results_dir), "",
              "| category | reading | " + " | ".join(rows) + " |", "|---|---|" + "---|" * len(rows)]
    literal_means = (None if literal is None else
                     literal.groupby(["category", "mode"]).unit_area.agg(["mean", "std"]).unstack())
    for category, row in table4.iterrows():
        cells = [f"{row[f'ours, {m}']:.2f}"
                 + (f" ± {row[f'ours, {m}, std over splits']:.2f}" if pd.notna(row.get(f"ours, {m}, std over splits")) else "")
                 + (f" ({row[f'paper, {m}']:.2f})" if pd.notna(row.get(f"paper, {m}")) else "") for m in rows]
        lines.append(f"| {category} | default | " + " | ".join(cells) + " |")
        if literal_means is not None and category in literal_means.index:
            means = literal_means.loc[category]
            lines.append(f"| {category} | `{PLAIN_READING}` | " + " | ".join(
                "" if pd.isna(means.get(("mean", m))) else f"{means[('mean', m)]:.2f}"
                + (f" ± {means[('std', m)]:.2f}" if pd.notna(means.get(("std", m))) else "") for m in rows) + " |")
    lines += ["", f"Paired, per split and category: nonuniform minus each other row, the mean over {len(ablation_splits)} "
              "split(s) and the categories with its 95 % bootstrap interval, read by the claims ledger's rule: "
              + "; ".join(f"{name}: " + "; ".join(f"{d} ({d.verdict})" for d in (
                  figure_effects.paired_over_splits(runs, "nonuniform", m) for m in rows[1:] if m in set(runs["mode"])))
                  for name, runs in readings) + "."]
    coseg = results_dir / "table2_coseg.csv"
    if coseg.is_file():
        table2 = pd.read_csv(coseg, index_col=0)
        peer_columns = [c for c in table2.select_dtypes("number").columns  # ours and peers in one metric: no v1 (unit area)
                        if not c.startswith(("ours", "n_", "v1"))]
        lines += ["", "COSEG large sets as MeshCNN distributes them ([notebook](notebooks/executed/table2_coseg.ipynb)); "
                  "not the paper's data (its Table II uses the small sets), so compared with peers that report on these; "
                  "ours as the share of faces (the metric of the PD-MeshNet face column), here and in the ledger:",
                  "", "| set | ours, share of faces | " + " | ".join(peer_columns) + " |",
                  "|---|---|" + "---|" * len(peer_columns)]
        for entry, row in table2.iterrows():
            lines.append(_markdown_row(entry, [row[ledger.COSEG_METRIC], *(row[c] for c in peer_columns)]))
    human = results_dir / "table3_human.csv"
    if human.is_file():
        table3 = pd.read_csv(human)
        lines += ["", "Human body set as MeshCNN distributes it ([notebook](notebooks/executed/table3_human.ipynb)); "
                  "the paper's split; the paper does not say whether it used these simplified meshes, so compared with "
                  "peers that report on them:", "",
                  "| method | accuracy | metric |", "|---|---|---|"]
        lines += [f"| {row.method} | {row.accuracy:.2f} | {row.metric} |" for row in table3.itertuples()]
    return "\n".join(lines)


def update_readme(readme: Path, results_dir: Path) -> None:
    """Replace the blocks between the headline and the ledger markers of ``readme`` with :func:`headline` and the ledger."""
    text = readme.read_text()
    for first, last, block in ((HEADLINE_START, HEADLINE_END, headline(results_dir)),
                               (LEDGER_START, LEDGER_END, ledger.markdown(ledger.ledger(results_dir)))):
        start, end = text.index(first) + len(first), text.index(last)
        text = text[:start] + "\n" + block + "\n" + text[end:]
    readme.write_text(text)
