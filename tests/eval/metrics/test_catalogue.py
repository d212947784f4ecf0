"""eval.metrics.catalogue: one spec per metric, read by the record, the tables and the gate."""

import math

import pytest

from eval.metrics import catalogue
from eval.metrics.catalogue import (
    ATE_RMSE,
    CATALOGUE,
    DEPTH_PERCENT_CORRECT,
    FAMILIES,
    ROT_DEG_ORIENT_RMSE,
    TRACKED_SHARE,
    CatalogueError,
    MetricSpec,
    Shown,
    check_catalogue,
    spec_of,
)
from slamcommon import agent_keys


def test_the_catalogue_is_consistent():
    check_catalogue()


@pytest.mark.parametrize(("specs", "families", "message"), [
    ((ATE_RMSE, ATE_RMSE), (), "twice"),
    ((MetricSpec("ate_*", "x"),), (), "is a pattern"),
    ((), (MetricSpec("ate_rmse_x", "x"),), "no pattern"),
    ((MetricSpec("x", "x", group="pose"),), (), "group 'pose'"),
    ((MetricSpec("x", "x", bounds=(1.0, 0.0)),), (), "low > high"),
    ((MetricSpec("x", "x", shown=(Shown("t", 0),)), MetricSpec("y", "y", shown=(Shown("t", 0),))), (), "taken"),
])
def test_a_catalogue_contradicting_itself_is_refused(specs, families, message):
    with pytest.raises(CatalogueError, match=message):
        check_catalogue(specs, families)


def test_the_agents_own_keys_are_the_judges():
    assert TRACKED_SHARE.key == agent_keys.TRACKED_SHARE
    assert catalogue.FRAMES.key == agent_keys.FRAMES


@pytest.mark.parametrize(("name", "bounds", "direction", "group"), [
    (ROT_DEG_ORIENT_RMSE.key, (0.0, 180.0), "lower", "trajectory"),
    ("rpe_rot_deg_median", (0.0, 180.0), "lower", "trajectory"),  # a family: an angle too
    ("rot_deg_orient_max", (0.0, 180.0), "lower", "trajectory"),
    (DEPTH_PERCENT_CORRECT.key, (0.0, 100.0), "higher", "depth"),
    (TRACKED_SHARE.key, (0.0, 1.0), "higher", "trajectory"),
    ("semantic_iou_wall", (0.0, 1.0), "higher", "semantic"),
    ("rpe_dist_m_p10", (0.0, math.inf), None, "trajectory"),  # a distance, neither better
    ("scale", (0.0, math.inf), None, "trajectory"),
])
def test_known_metrics_have_their_range_direction_and_group(name, bounds, direction, group):
    spec = spec_of(name)
    assert spec is not None
    assert spec.bounds == bounds and spec.table_direction == direction and spec.group == group


def test_a_name_of_no_spec_has_none():
    assert spec_of("no_such_metric") is None
    assert catalogue.group_of("no_such_metric") is None and catalogue.better_direction("no_such_metric") is None


def test_an_exact_spec_agrees_with_its_familys_group():
    for spec in CATALOGUE:
        family = next((f for f in FAMILIES if spec_of(spec.key, specs=(), families=(f,)) is not None), None)
        if family is not None:
            assert family.group == spec.group, spec.key


def test_blocks_are_read_in_their_places_order():
    assert catalogue.blocks(catalogue.TABLE1) == ((ATE_RMSE.label, ATE_RMSE.key),
                                                  (DEPTH_PERCENT_CORRECT.label, DEPTH_PERCENT_CORRECT.key))
    rotation = [key for _, key in catalogue.blocks(catalogue.ROTATION)]
    assert rotation[0] == TRACKED_SHARE.key and rotation[-1] == DEPTH_PERCENT_CORRECT.key
    assert ATE_RMSE.label_at(catalogue.RUN_FACTS) == "ATE (headline)" and ATE_RMSE.label_at("nowhere") == ATE_RMSE.label


def test_gated_keys_are_the_flagged_specs():
    gated = catalogue.keys(gated=True)
    assert set(gated) == {s.key for s in CATALOGUE if s.gated}
    assert {ATE_RMSE.key, DEPTH_PERCENT_CORRECT.key, TRACKED_SHARE.key, ROT_DEG_ORIENT_RMSE.key} <= set(gated)


def test_gate_rules_follow_the_catalogue_order_with_families_last():
    rules = catalogue.gate_rules()
    patterns = [p for p, *_ in rules]
    assert patterns.index(f"*{ATE_RMSE.key}") < patterns.index("*ate_*")
    assert ("*" + TRACKED_SHARE.key, "higher", 0.005, 0.0) in rules
    # a spec that is neither lower- nor higher-better is gated as lower (the gate's fallback direction)
    assert ("*rpe_dist_m_*", "lower", 0.002, 0.10) in rules
    assert all(lo <= hi for _, lo, hi in catalogue.bound_rules())
