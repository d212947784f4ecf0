"""``cnnslam regress BASELINE RUN``: a missing, unreadable or malformed file is exit 2 with one line; a regression
(tracked -> lost included) is exit 1; a passing run exit 0."""

import json

import pytest

from cnnslam.cli import main

GOOD = {"schema": "cnnslam-baseline/2", "metrics": {"s/A/ate_rmse": 0.1, "s/A/tracked_share": 1.0}}


@pytest.fixture
def files(tmp_path):
    base, run = tmp_path / "base.json", tmp_path / "run.json"
    base.write_text(json.dumps(GOOD))
    run.write_text(json.dumps({"metrics": {"s/A/ate_rmse": 0.1, "s/A/tracked_share": 1.0}}))
    return base, run


def _one_line_error(capsys, needle):
    captured = capsys.readouterr()
    err = captured.err.strip().splitlines()
    assert len(err) == 1 and needle in err[0] and err[0].startswith("cnnslam regress: error:"), captured.err
    assert "Traceback" not in captured.err and "PASS" not in captured.out


def test_a_passing_run_exits_0(files, capsys):
    assert main(["regress", *map(str, files)]) == 0
    assert capsys.readouterr().out.strip().splitlines()[-1].startswith("PASS")


def test_a_missing_baseline_or_run_file_exits_2(files, tmp_path, capsys):
    base, run = files
    assert main(["regress", str(tmp_path / "MISSING.json"), str(run)]) == 2
    _one_line_error(capsys, "MISSING.json: cannot read")
    assert main(["regress", str(base), str(tmp_path / "NORUN.json")]) == 2
    _one_line_error(capsys, "NORUN.json: cannot read")
    assert main(["regress", str(tmp_path), str(run)]) == 2  # a folder: unreadable as a file
    _one_line_error(capsys, "cannot read")


@pytest.mark.parametrize(
    ("content", "needle"),
    [
        ('{"metrics": ', "not valid JSON"),
        ('{"schema": "cnnslam-run/1", "metrics": {"s/A/ate_rmse": 0.1}}', "is not a baseline's"),
        ('{"metrics": {}}', "holds no figures"),
        ('{"metrics": {"s/A/ate_rmse": 0.1}, "calibration": []}', "'calibration' is an object"),
        ('{"metrics": {"s/A/ate_rmse": 0.1}, "tolerances": 5}', "each tolerance is"),
        ('{"metrics": {"s/A/rot_deg_rmse": 51.9}, "calibrated": {"s/A/rot_deg_rmse": {"allowed": 182}}}',
         "can never fail inside the metric's bounds 0..180"),
        ('{"metrics": {"s/A/ate_rmse": 0.1}, "tolerances": [{"pattern": "*share"}, {"pattern": "*tracked_share"}]}',
         "can never match"),
    ],
)
def test_a_malformed_baseline_exits_2_with_one_line(files, capsys, content, needle):
    base, run = files
    base.write_text(content)
    assert main(["regress", str(base), str(run)]) == 2
    _one_line_error(capsys, needle)


def test_tracked_to_lost_exits_1_whatever_the_tolerance(files, capsys):
    base, run = files
    loose = {**GOOD, "tolerances": [{"pattern": "*tracked_share", "direction": "higher", "abs": 0.9, "rel": 0.0}]}
    base.write_text(json.dumps(loose))
    run.write_text(json.dumps({"metrics": {"s/A/ate_rmse": 0.1, "s/A/tracked_share": 0.2}}))  # within 0.9
    assert main(["regress", str(base), str(run)]) == 1
    out = capsys.readouterr().out
    assert "tracked -> lost: s/A/tracked_share" in out and "FAIL" in out
