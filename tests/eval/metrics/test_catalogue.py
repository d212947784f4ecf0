"""eval.metrics.catalogue: one spec per metric, read by the record, the tables and the gate."""

import json
import math
import os
import shutil
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
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


# ------------------------------------------------------------------------------------------ a new metric, end to end
REPO = Path(__file__).resolve().parents[3]
NEW_KEY = "path_ratio"
NEW_SPEC = f'''
PATH_RATIO = MetricSpec("{NEW_KEY}", "Path ratio", "", "match", "trajectory", 3, (0.0, 0.05), NON_NEGATIVE,
                        gated=True, shown=_shown((QUICK, 7)))
'''
NEW_COMPUTATION = f'''        m["{NEW_KEY}"] = self.length_est / self.length_gt if self.length_gt > 0 else math.nan
'''
PROBE = f'''
import json, math
from types import SimpleNamespace
import numpy as np
from eval.bench import regress
from eval.metrics.results import evaluate_episode, runs_frame
from eval.reports.suite_reports import QUICK_BLOCKS
from eval.reports.tables import table1, table_to_markdown

n = 6
gt = np.repeat(np.eye(4)[None], n, axis=0)
gt[:, 0, 3] = np.linspace(0.0, 1.0, n)
est = gt.copy()
est[:, 0, 3] *= 1.25
episode = SimpleNamespace(sequence="s", agent="a", timestamps=np.arange(n) / 30.0, T_world_cam_est=est,
                          T_world_cam_gt=gt, tracked=np.ones(n, bool), keyframes=[], keyframe_gt=[],
                          step_seconds=np.full(n, 0.01), uses_ground_truth=False, extras={{}})
record = evaluate_episode(episode, method="m")
markdown = table_to_markdown(table1(runs_frame([record]), blocks=QUICK_BLOCKS))
figures = regress.gate_metrics([record])
name = "s/m/{NEW_KEY}"
baseline = regress.Baseline(dict(figures))
moved = regress.compare(baseline, {{**figures, name: figures[name] * 1.2}})
print(json.dumps({{"record": record.metrics.get("{NEW_KEY}"), "table": "Path ratio" in markdown,
                  "rule": baseline.tolerance_for(name).pattern,
                  "status": next(r.status for r in moved.rows if r.metric == name)}}))
'''


def _insert(path: Path, anchor: str, text: str, before: bool = True) -> None:
    source = path.read_text()
    assert source.count(anchor) == 1, f"{path.name}: anchor {anchor!r} not found once"
    path.write_text(source.replace(anchor, text + anchor if before else anchor + text))


def _changed_files(copy: Path) -> list[str]:
    changed = []
    for package in ("eval", "slamcommon"):
        for path in sorted((copy / package).rglob("*.py")):
            original = REPO / path.relative_to(copy)
            if not original.is_file() or original.read_bytes() != path.read_bytes():
                changed.append(str(path.relative_to(copy)))
    return changed


@pytest.mark.slow
def test_a_new_metric_is_one_spec_and_one_computation(tmp_path):
    """The CONTRIBUTING recipe "a new metric", done in a copy of the judge: its spec in the catalogue (gated, shown
    in the quick table) and its computation in the trajectory metrics. The run record holds it, the quick table
    shows it, and the gate compares it under its own rule; no other file changes."""
    copy = tmp_path / "tree"
    for package in ("eval", "slamcommon"):
        shutil.copytree(REPO / package, copy / package, ignore=shutil.ignore_patterns("__pycache__"))
    catalogue_py = copy / "eval" / "metrics" / "catalogue.py"
    _insert(catalogue_py, "\n# The exact specs, in the gate's order", NEW_SPEC)
    _insert(catalogue_py, "\n)\n# The families", " PATH_RATIO,")
    _insert(copy / "eval" / "metrics" / "trajectory_metrics.py", "        for rel in self.relative:\n",
            NEW_COMPUTATION)
    assert _changed_files(copy) == ["eval/metrics/catalogue.py", "eval/metrics/trajectory_metrics.py"]
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(copy), str(REPO)])}
    done = subprocess.run([sys.executable, "-c", PROBE], cwd=copy, env=env, capture_output=True, text=True,
                          timeout=300)
    assert done.returncode == 0, done.stderr[-3000:]
    seen = json.loads(done.stdout.strip().splitlines()[-1])
    assert seen["record"] == pytest.approx(1.25)
    assert seen["table"] is True
    assert seen["rule"] == f"*{NEW_KEY}"
    assert seen["status"] == "regressed"


def test_the_gates_rules_judge_every_figure_as_the_committed_baselines_rules_do():
    """The default rules derived from the catalogue give every figure of the committed quick baseline, and every
    metric of a scored run, the direction and allowed change that the baseline's own rule list gives it."""
    from eval.bench.gate_baseline import Baseline, load_baseline
    from eval.metrics.results import evaluate_episode

    path = REPO / "results" / "baselines" / "quick.json"
    if not path.is_file():
        pytest.skip(f"{path} is absent")
    committed = load_baseline(path, crossable=False)
    derived = Baseline({})
    n = 5
    gt = np.repeat(np.eye(4)[None], n, axis=0)
    gt[:, 0, 3] = np.linspace(0.0, 1.0, n)
    episode = SimpleNamespace(sequence="s", agent="a", timestamps=np.arange(n) / 30.0, T_world_cam_est=gt.copy(),
                              T_world_cam_gt=gt, tracked=np.ones(n, bool), keyframes=[], keyframe_gt=[],
                              step_seconds=np.full(n, 0.01))
    names = {*committed.metrics, *(f"s/m/{k}" for k in evaluate_episode(episode).metrics)}
    assert len(names) > 50
    for name in sorted(names):
        old, new = committed.tolerance_for(name), derived.tolerance_for(name)
        assert (new.direction, new.abs, new.rel) == (old.direction, old.abs, old.rel), name
