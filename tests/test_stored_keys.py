"""Every stored run is found again: its key, recomputed from the settings it records, is the key it is stored under.

A rename, a moved module or a new setting must not change what decides a
key, or the study would retrain what it already holds. Validation cells
add their fold to the data options, as :class:`anseg.study.validate.Cell` does.
"""

from __future__ import annotations

import json
from dataclasses import fields

import pytest

from anseg.pipeline import SegmentConfig
from anseg.study.store import REPO, SETTINGS_ADDED_LATER, Experiment
from anseg.train import TrainConfig

STORES = ("results/runs", "results/validation/runs")


def typed(config_class, part: str, recorded: dict):
    """The config a record describes, or None where it names a setting this code lacks.

    Lists come back as tuples; a setting added after the record was stored
    takes the value older results ran with (:data:`SETTINGS_ADDED_LATER`).
    """
    known = {f.name for f in fields(config_class)}
    if set(recorded) - known:
        return None
    defaults = config_class()
    values = {**{k: v for k, v in SETTINGS_ADDED_LATER[part].items() if k in known}, **recorded}
    return config_class(**{k: tuple(v) if isinstance(getattr(defaults, k), tuple) else v for k, v in values.items()})


def recomputed_key(record: dict) -> str | None:
    segment, train = typed(SegmentConfig, "segment", record["segment"]), typed(TrainConfig, "train", record["train"])
    if segment is None or train is None:
        return None
    options = dict(record.get("dataset_options") or {})
    if "fold" in record:  # a validation cell
        options["validation"] = {"folds": record["folds"], "fold": record["fold"]}
    experiment = Experiment(record["dataset"], record["category"], record["split_index"], segment, train)
    return experiment.key(options or None)


@pytest.mark.parametrize("store", STORES)
def test_every_stored_run_keeps_its_key(store):
    records = [json.loads(p.read_text()) for p in sorted((REPO / store).glob("*.json"))]
    if not records:
        pytest.skip(f"nothing stored under {store}")
    moved = [r["key"] for r in records if recomputed_key(r) not in (r["key"], None)]
    unreadable = [r["key"] for r in records if recomputed_key(r) is None]
    assert moved == []
    assert len(unreadable) <= len(records) // 10, f"{len(unreadable)} records name settings this code lacks"
