"""Which PSB test meshes the default's settings were chosen on: split 0 is the clean test, splits 1-4 are not.

The default's settings were chosen on the 12 training meshes of PSB split 0
(cross-validation, ``python -m anseg.study.validate``), never on a test
split. Splits 1-4 are other shuffles of the same meshes, so their test
meshes include meshes of split 0's training set: a result on those splits
reads meshes the settings were selected on, which favours the default.
Every table and ledger row that reads splits 1-4 says how many of their
test meshes that is, counted here from ``anseg/datasets/psb_splits.json``
(never typed), so the share follows the splits file and the units read.
"""

from __future__ import annotations

from collections.abc import Iterable

SELECTED_ON = 0  # the split whose training meshes the settings were chosen on


def overlap(units: Iterable[tuple[str, int]]) -> tuple[int, int]:
    """Of the test meshes of the PSB (category, split) ``units`` other than split 0's: how many are among split 0's
    training meshes of their category, and how many there are (each unit counted once)."""
    from anseg.datasets.psb import psb_split

    selected, tested = 0, 0
    for category, split in sorted(set(units)):
        if split == SELECTED_ON:
            continue
        test = psb_split(category, split)["test"]
        selected += len(set(test) & set(psb_split(category, SELECTED_ON)["train"]))
        tested += len(test)
    return selected, tested


def note(units: Iterable[tuple[str, int]]) -> str:
    """A clause for beside a result that reads splits 1-4: the share of their test meshes the settings were chosen
    on; "" where the units read split 0 alone."""
    selected, tested = overlap(units)
    if not tested:
        return ""
    return (f"{selected} of the {tested} test meshes of splits other than {SELECTED_ON} ({percent(selected, tested)}) "
            f"are split {SELECTED_ON}'s training meshes, which the settings were chosen on")


def percent(selected: int, tested: int) -> str:
    return f"{100 * selected / tested:.0f} %"


def brief(units: Iterable[tuple[str, int]]) -> str:
    """:func:`note` in three words for a row of a table whose caption says what "selection" means; "" for split 0."""
    selected, tested = overlap(units)
    return f"selection {percent(selected, tested)} ({selected} of {tested})" if tested else ""


def psb_note(categories: Iterable[str], splits: Iterable[int]) -> str:
    """:func:`note` for every split of every category of a table."""
    splits = list(splits)
    return note((category, split) for category in categories for split in splits)
