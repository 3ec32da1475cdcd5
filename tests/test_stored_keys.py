"""Every stored run is found again: its key, recomputed from the settings it records, is the key it is stored under.

A rename, a moved module, a new setting or a retired switch must not change
what decides a key, or the study would retrain what it already holds.
Validation cells add their fold to the data options, as
:class:`anseg.study.validate.Cell` does. A record that names a retired switch
switched on cannot be read by today's code (it replays at its own revision).
"""

from __future__ import annotations

import json

import pytest

from anseg.study.store import REPO, Experiment, recorded_settings

STORES = ("results/runs", "results/validation/runs")


def recomputed_key(record: dict) -> str | None:
    try:
        segment, train = recorded_settings(record)
    except ValueError:
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
    keys = {r["key"]: recomputed_key(r) for r in records}
    assert [stored for stored, key in keys.items() if key not in (stored, None)] == []
    unreadable = [stored for stored, key in keys.items() if key is None]
    assert len(unreadable) <= len(records) // 10, f"{len(unreadable)} records name settings this code lacks"


def test_a_retired_switch_reads_where_it_was_off_and_is_refused_where_it_was_on():
    record = {"key": "k", "segment": {}, "train": {"position_pairs": 0, "epochs": 3}}
    assert recorded_settings(record)[1].epochs == 3
    with pytest.raises(ValueError, match="replay it at its own revision"):
        recorded_settings({**record, "train": {"position_pairs": 8}})
