"""The one paired test every claim of the ledger is read by: an effect per unit, its mean and 95 % bootstrap interval.

Units are (category, split) pairs, resampled in two stages (categories, then
the splits inside each, since categories differ far more than splits), test
meshes of one model per split (models, then meshes), or test meshes of one
model, resampled in one stage. The interval above 0 reads ``reproduced``,
below 0 ``not reproduced``, holding 0 or resting on one unit ``not
distinguishable``; a claim of several parts needs every part; a claim read two
ways (:func:`across_readings`) stands where both readings agree and
otherwise ``depends on the reading``. :data:`DRAWS`
draws from a generator seeded with :data:`SEED`: a result gives the same
interval every time.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

REPRODUCED, NOT_REPRODUCED, TIED, UNTESTED = "reproduced", "not reproduced", "not distinguishable", "cannot be tested here"
DEPENDS = "depends on the reading"
DRAWS, SEED = 10_000, 0


class MissingResult(Exception):
    """A result file a claim needs is not there."""


@dataclass(frozen=True, eq=False)
class Effect:
    """A paired effect in a claim's favour, per unit, with its mean and 95 % bootstrap interval (:func:`effect`)."""

    name: str
    values: object  # pandas Series: the effect per unit, indexed by (category, split) or by one level (mesh, split)
    mean: float
    low: float
    high: float

    @property
    def units(self) -> str:
        index = self.values.index
        if index.nlevels == 2:
            counts = self.values.groupby(level=0).size()
            inner = f"{counts.min()}" if counts.min() == counts.max() else f"{counts.min()}-{counts.max()}"
            if list(index.names) == ["split", "mesh"]:  # one trained model per split, each scored on its test meshes
                return (f"{len(counts)} model{'' if len(counts) == 1 else 's'} (one per split) × {inner} test "
                        f"mesh{'' if inner == '1' else 'es'}")
            return f"{len(counts)} categor{'y' if len(counts) == 1 else 'ies'} × {inner} split{'' if inner == '1' else 's'}"
        noun = "test mesh" if index.name == "mesh" else index.name or "unit"
        return f"{len(index)} {noun}{'' if len(index) == 1 else 'es' if noun.endswith('sh') else 's'}"

    @property
    def verdict(self) -> str:
        if len(self.values) < 2:
            return TIED
        return REPRODUCED if self.low > 0 else NOT_REPRODUCED if self.high < 0 else TIED

    def __str__(self) -> str:
        interval = "one unit, no interval" if len(self.values) < 2 else f"[{self.low:+.2f}, {self.high:+.2f}]"
        return f"{self.name} {self.mean:+.2f} {interval} over {self.units}"


def effect(values, name: str) -> Effect:
    """The mean of ``values`` (a Series of per-unit effects) and its 95 % percentile bootstrap interval.

    Indexed by two levels, (category, split) or (split, mesh) for one
    model per split: two-stage, the outer units drawn with replacement, then
    as many inner units as the outer one has, drawn with replacement inside
    it; the statistic is the mean of the outer means (so a model's spread
    counts, not only its meshes'). Indexed by one level: one stage. :data:`DRAWS` draws from a generator
    seeded with :data:`SEED`, so a result gives the same interval every time.
    """
    values = values.dropna()
    rng = np.random.default_rng(SEED)
    if len(values) == 0:
        raise MissingResult(f"no units to measure {name} on")
    if values.index.nlevels == 2:
        groups = [group.to_numpy() for _, group in values.groupby(level=0)]
        counts = np.array([len(g) for g in groups])
        padded = np.zeros((len(groups), counts.max()))
        for row, group in enumerate(groups):
            padded[row, :len(group)] = group
        mean = float(np.mean([g.mean() for g in groups]))
        drawn = rng.integers(len(groups), size=(DRAWS, len(groups)))  # stage 1: categories
        n = counts[drawn][..., None]
        picks = (rng.random((DRAWS, len(groups), counts.max())) * n).astype(int)  # stage 2: splits inside each
        kept = np.arange(counts.max()) < n  # a category of fewer splits draws only as many
        statistics = (np.where(kept, padded[drawn[..., None], picks], 0.0).sum(-1) / n[..., 0]).mean(-1)
    else:
        array = values.to_numpy()
        mean = float(array.mean())
        statistics = array[rng.integers(len(array), size=(DRAWS, len(array)))].mean(-1)
    low, high = np.percentile(statistics, [2.5, 97.5])
    return Effect(name, values, mean, float(low), float(high))


def combined(*effects: Effect) -> str:
    """A claim of several parts: reproduced when every part is, not reproduced when any part is, else not distinguishable."""
    verdicts = [e.verdict for e in effects]
    return NOT_REPRODUCED if NOT_REPRODUCED in verdicts else REPRODUCED if set(verdicts) == {REPRODUCED} else TIED


def across_readings(*verdicts: str) -> str:
    """One claim judged under several readings of the method, each by the rule: their verdict where they all agree,
    else :data:`DEPENDS` (a verdict that holds under one reading alone is not the paper's claim reproduced or refuted)."""
    return verdicts[0] if len(set(verdicts)) == 1 else DEPENDS
