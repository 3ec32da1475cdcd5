"""Named configurations and the field=value override syntax shared by the CLI, validation and notebooks."""

from __future__ import annotations

from dataclasses import replace

import pytest

from anseg.cli import main
from anseg.configs import configuration, overrides
from anseg.features import DEFAULT_GROUPS
from anseg.pipeline import SegmentConfig
from anseg.train import TrainConfig


def test_default_is_the_dataclass_defaults():
    assert configuration("default") == (SegmentConfig(), TrainConfig())


def test_paper_is_the_plain_reading():
    segment, train = configuration("paper")
    assert segment.groups == DEFAULT_GROUPS and "smooth" not in segment.groups
    assert segment.combine == "coarsest" and segment.priority == "score" and segment.density_range == float("inf")
    assert segment.smooth_weight == 1.0
    # the two readings the paper's text leaves open, chosen on held-out training meshes
    assert segment.local_scale == "relative" and segment.once_per_pass
    assert train.attention_weight == 0.0 and not train.embed_norm and train.average_last == 0


def test_v1_is_the_reading_the_committed_tables_ran_with():
    segment, train = configuration("v1")
    assert segment.groups == DEFAULT_GROUPS + ("smooth",) and segment.local_scale == "unit_area"
    assert segment.priority == "score" and segment.smooth_weight == 1.0 and train.average_last == 0
    assert configuration("default") != (segment, train)


def test_fast_is_the_default_with_larger_patches_and_fewer_rebuilds():
    segment, train = configuration("fast")
    assert (segment.patch_size, train.recollapse_every) == (32, 10)
    assert (SegmentConfig(), TrainConfig()) == (replace(segment, patch_size=SegmentConfig().patch_size),
                                                 replace(train, recollapse_every=TrainConfig().recollapse_every))


def test_grad_pose_is_the_arm_the_suite_confirm_adopted():
    """The named configuration trains what the confirm's grad-pose cells trained (their records' settings)."""
    import json

    from anseg.study.store import REPO, recorded_settings

    cells = [json.loads(p.read_text()) for p in sorted((REPO / "results/validation/confirm-grad-pose/runs").glob("*.json"))]
    adopted = [recorded_settings(c) for c in cells if c["arm"] == "grad-pose"]
    if not adopted:
        pytest.skip("the grad-pose confirm's cells are not in this checkout")
    segment, train = configuration("grad-pose")
    for cell_segment, cell_train in adopted:
        assert cell_segment == replace(segment, seed=cell_segment.seed)
        assert cell_train == replace(train, seed=cell_train.seed, epochs=cell_train.epochs)
    assert configuration("default") != (segment, train)


def test_overrides_go_on_top_of_a_named_configuration():
    segment, train = configuration("paper", "combine=all,train.width=128")
    assert segment.combine == "all" and train.width == 128 and train.attention_weight == 0.0
    assert overrides("default", "ratio=0.4") == ({"ratio": 0.4}, {})
    with pytest.raises(ValueError, match="unknown configuration"):
        configuration("fancy")


def test_cli_train_refuses_a_bad_setting_before_reading_data(capsys):
    assert main(["train", "--config", "paper", "--set", "train.width=wide", "-o", "x.pt"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "train.width" in err
    assert main(["train", "--set", "combine=some", "-o", "x.pt"]) == 2
    assert "combine must be one of" in capsys.readouterr().err
