"""``cnnslam map``: every argument it cannot use is refused with exit 2 and one line naming the value and what is
valid, before the agent runs and before anything is written."""

from __future__ import annotations

import pytest

from cnnslam.cli import main

GT_AGENT = "cnnslam.agent:GroundTruthAidedAgent"


def _refuse_writes(*args, **kwargs):
    raise PermissionError(13, "Permission denied")


@pytest.mark.parametrize(("options", "named", "valid"), [
    (["ofice0"], "unknown sequence 'ofice0'", "valid sequences: office0, "),
    (["office0", "--frames", "0"], "--frames 0: office0 has 1500 frames", "give 1..1500"),
    (["office0", "--frames", "99999"], "--frames 99999: office0 has 1500 frames", "give 1..1500"),
    (["office0", "--length", "10", "--frames", "20"], "--frames 20: office0 has 10 frames", "give 1..10"),
    (["office0", "--length", "1"], "--length 1", "at least 2 frames"),
    (["office0", "--voxel", "0"], "--voxel 0", "positive number of metres"),
    (["office0", "--gt-spacing", "-1"], "--gt-spacing -1", "positive number of metres"),
    (["office0", "--threshold", "nan"], "--threshold nan", "positive number of metres"),
    (["office0", "--label-distance", "0"], "--label-distance 0", "positive number of metres"),
    (["office0", "--alignment", "foo"], "--alignment: unknown alignment 'foo'", "valid alignments: se3, sim3"),
    (["office0", "--agent-options", "[1]"], "--agent-options must be a JSON object, got '[1]'", "JSON object"),
    (["office0", "--agent-options", "{"], "--agent-options '{': not JSON", "give a JSON object"),
    (["office0", "--agent", GT_AGENT, "--agent-options", '{"x": 1}'], '--agent-options {"x": 1}',
     "unexpected keyword argument 'x'"),
    (["office0", "--agent", "no_such_module:Agent"], "cannot import the agent module 'no_such_module'",
     "no_such_module:Agent"),
    (["office0", "--agent", GT_AGENT, "--renderer", "foo"], "unknown renderer 'foo'", "valid renderers: mujoco"),
    (["office0", "--out", "{tmp}/file"], "--out {tmp}/file: a file, not a folder", "name a folder"),
    (["office0", "--out", "{tmp}/file/sub"], "--out {tmp}/file/sub: {tmp}/file is a file", "under a folder"),
    (["office0", "--out", "READ_ONLY"], "--out {tmp}/new: cannot write in {tmp}/new (Permission denied)",
     "name a path this user can"),
    (["office0", "--figure", "{tmp}/map.xyz"], "--figure {tmp}/map.xyz: matplotlib cannot write", ".png"),
    (["office0", "--figure", "{tmp}/file/map.png"], "--figure {tmp}/file/map.png: {tmp}/file is a file", "under a"),
    (["office0", "--figure", "{tmp}/folder.png"], "--figure {tmp}/folder.png: a folder, not a file", "name a file"),
])
def test_bad_arguments_exit_2_in_one_line_before_the_agent_runs(tmp_path, monkeypatch, capsys, options, named,
                                                                  valid):
    import sim_envs.driver
    import slamcommon.output_paths as output_paths

    def no_run(*args, **kwargs):
        raise AssertionError("the episode ran")

    monkeypatch.setattr(sim_envs.driver, "run_episode", no_run)
    if "READ_ONLY" in options:  # as the check sees a folder it may not write (root may write anywhere)
        monkeypatch.setattr(output_paths.tempfile, "NamedTemporaryFile", _refuse_writes)
        options = [o.replace("READ_ONLY", "{tmp}/new") for o in options]
    (tmp_path / "file").write_text("x")
    (tmp_path / "folder.png").mkdir()
    monkeypatch.chdir(tmp_path)  # the default --out (runs/map/<sequence>) lands here, if anywhere
    before = sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*"))
    options = [o.replace("{tmp}", str(tmp_path)) for o in options]
    out = [] if "--out" in options else ["--out", str(tmp_path / "out")]
    assert main(["map", *options, *out, "--no-progress"]) == 2
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("cnnslam map: error: "), captured.err
    assert named.replace("{tmp}", str(tmp_path)) in lines[0] and valid in lines[0]
    assert captured.out == "" and sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*")) == before


def test_the_unknown_alignment_message_is_exactly_one_line(capsys):
    assert main(["map", "office0", "--alignment", "foo"]) == 2
    err = capsys.readouterr().err
    assert err == ("cnnslam map: error: --alignment: unknown alignment 'foo'; valid alignments: se3, sim3, origin, "
                   "none\n")
