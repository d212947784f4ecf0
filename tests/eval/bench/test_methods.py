"""The method table: entries, seeds, metric groups, availability checks, external methods."""

import textwrap

import pytest

from eval.bench.methods import (
    METHODS_FILE,
    Method,
    MethodError,
    check_available,
    check_methods,
    external_method,
    get_method,
    load_methods,
    parse_external,
    parse_methods,
)
from eval.bench.suites import ABLATION_METHODS, QUICK_METHODS, TABLE1_METHODS

FLAT = {
    "ate_rmse": 0.1,
    "rot_deg_rmse": 1.0,
    "rpe_trans_rmse": 0.01,
    "scale": 1.1,
    "scale_error": 0.09,
    "length_gt_m": 2.0,
    "tracked_share": 1.0,
    "frames": 60.0,
    "depth_percent_correct": 20.0,
    "depth_keyframes": 3.0,
    "semantic_mean_iou": 0.4,
    "step_ms_mean": 12.0,
    "fps": 80.0,
}


def test_the_default_table_has_every_method_the_suites_name():
    table = load_methods()
    for name in {*TABLE1_METHODS, *ABLATION_METHODS, *QUICK_METHODS}:
        assert name in table
    assert table["CNN-SLAM"].entry_point == "cnnslam.agent:CnnSlamAgent"
    assert dict(table["CNN-SLAM"].kwargs) == {"preset": "cnn_slam", "threads": False}
    assert table["LSD-BS"].entry_point == "cnnslam.agent:GroundTruthAidedAgent"
    assert table["REMODE"].metrics == ("depth",)  # no ATE column, as in the paper
    assert table["oracle"].entry_point == "sim_envs.agents:OracleAgent"
    # every paper column of Table 1 is a method, named as in eval.reports.paper_table1
    assert {m.paper for m in table.values() if m.paper} == {"CNN-SLAM", "LSD-BS", "LSD", "ORB", "Laina", "REMODE"}


def test_seed_goes_where_the_table_says():
    table = load_methods()
    # the network's methods: the seed goes to the system and to the network's last-bit jitter
    assert table["CNN-SLAM"].agent_kwargs(7) == {"preset": "cnn_slam", "threads": False, "config": {"system.seed": 7},
                                                 "predictor_options": {"jitter_seed": 7}}
    assert table["Laina"].agent_kwargs(2) == {"predictor_options": {"jitter_seed": 2}}
    assert table["ORB"].agent_kwargs(3) == {"seed": 3}
    assert table["oracle"].agent_kwargs(5) == {"keyframe_every": 10}  # takes no seed
    merged = Method("m", entry_point="a:B", kwargs={"config": {"x.y": 1}}, seed="config.system.seed")
    assert merged.agent_kwargs(2) == {"config": {"x.y": 1, "system.seed": 2}}
    assert merged.agent_kwargs() == {"config": {"x.y": 1}}
    clash = Method("m", entry_point="a:B", kwargs={"config": 3}, seed="config.seed")
    with pytest.raises(MethodError, match="not a dict"):
        clash.agent_kwargs(1)


def test_metric_groups_select_what_applies():
    depth_only = Method("REMODE-like", entry_point="a:B", metrics=("depth",))
    assert depth_only.select_metrics(FLAT) == {"frames": 60.0, "depth_percent_correct": 20.0, "depth_keyframes": 3.0}
    full = Method("full", entry_point="a:B", metrics=("trajectory", "depth", "semantic"))
    kept = full.select_metrics(FLAT)
    assert set(FLAT) - set(kept) == {"step_ms_mean", "fps"}  # wall-clock figures never enter the metrics
    no_semantic = Method("x", entry_point="a:B").select_metrics(FLAT)
    assert "semantic_mean_iou" not in no_semantic and "scale_error" in no_semantic


def test_bad_definitions_name_the_problem():
    with pytest.raises(MethodError, match="entry_point must look like"):
        Method("x", entry_point="no_colon")
    with pytest.raises(MethodError, match="unknown metric group"):
        Method("x", entry_point="a:B", metrics=("speed",))
    with pytest.raises(MethodError, match="needs the folder"):
        Method("x", kind="external")
    with pytest.raises(MethodError, match="unknown field"):
        parse_methods({"methods": {"x": {"entry_point": "a:B", "colour": "red"}}})
    with pytest.raises(MethodError, match="valid methods: .*CNN-SLAM"):
        get_method("CNN_SLAM")
    assert Method("a b/c", entry_point="a:B").slug == "a_b_c"


def test_a_user_method_file(tmp_path):
    path = tmp_path / "mine.toml"
    path.write_text(
        textwrap.dedent(
            """
            [methods.Mine]
            entry_point = "sim_envs.agents:ConstantPoseAgent"
            kwargs = { tracked = false }
            metrics = ["trajectory"]
            """
        )
    )
    mine = load_methods(path)["Mine"]
    assert mine.agent_kwargs(0) == {"tracked": False} and mine.metrics == ("trajectory",)
    assert check_available(mine) is None
    (tmp_path / "broken.toml").write_text("[methods.X\n")
    with pytest.raises(MethodError, match="not valid TOML"):
        load_methods(tmp_path / "broken.toml")
    assert METHODS_FILE.name == "methods.toml"


# agents that are there and fail in step (a bug: a broken method) or lack a file (one that cannot run here)
STEP_FAILS_AGENTS = textwrap.dedent(
    """
    class StepFails:
        def reset(self, intrinsics, image_size):
            pass
        def step(self, observation):
            raise RuntimeError("a bug in step")
        def finish(self):
            return {}

    class NoWeights(StepFails):
        def step(self, observation):
            raise FileNotFoundError("no weights here")
    """
)


def test_availability_reports_why_a_method_cannot_run(tmp_path, monkeypatch):
    """Only what this machine lacks (a module, a file) makes a method one that "cannot run here"; an agent that is
    there and raises is a broken one: it stays in, and its runs fail, each with its error (the failure table)."""
    (tmp_path / "step_fails_agent.py").write_text(STEP_FAILS_AGENTS)
    monkeypatch.syspath_prepend(str(tmp_path))
    ok = Method("ok", entry_point="sim_envs.agents:OracleAgent")
    missing = Method("missing", entry_point="no_such_package.agent:Agent")
    no_attr = Method("no_attr", entry_point="sim_envs.agents:NoSuchAgent")
    bad_kwargs = Method("bad", entry_point="sim_envs.agents:OracleAgent", kwargs={"keyframe_every": 0})
    fails = Method("fails", entry_point="step_fails_agent:StepFails")
    no_weights = Method("no_weights", entry_point="step_fails_agent:NoWeights")
    assert check_available(ok) is None
    assert "cannot import 'no_such_package.agent'" in check_available(missing)
    assert "has no attribute 'NoSuchAgent'" in check_available(no_attr)
    assert "FileNotFoundError: no weights here" in check_available(no_weights)
    assert check_available(bad_kwargs) is None and check_available(fails) is None  # broken, not absent
    assert check_available(no_weights, build=False) is None  # import only
    checked = check_methods([ok, missing, fails, no_weights])
    assert [m.name for m in checked.available] == ["ok", "fails"] and set(checked.skipped) == {"missing", "no_weights"}


def test_external_methods(tmp_path):
    method = parse_external(f"MySLAM={tmp_path}")
    assert method.kind == "external" and method.folder == str(tmp_path.resolve()) and method.name == "MySLAM"
    assert check_available(method) is None
    assert "does not exist" in check_available(external_method("Gone", tmp_path / "nothing"))
    with pytest.raises(MethodError, match="NAME=FOLDER"):
        parse_external("no-equals-sign")
    assert method.describe()["folder"] == str(tmp_path.resolve()) and method.describe()["entry_point"] is None


def test_inputs_hash_files_and_name_bad_ones(tmp_path):
    weights = tmp_path / "w.pt"
    weights.write_bytes(b"first")
    method = Method("m", entry_point="a.b:C", inputs=[str(weights)])
    first = method.input_hashes()[str(weights)]
    assert first == "a7937b64b8caa58f03721bb6bacf5c78cb235febe0e70b1b84cd99541461a08e"  # sha256(b"first")
    weights.write_bytes(b"second")
    assert method.input_hashes()[str(weights)] != first
    # "package:path" is looked up inside the package's folder
    table = Method("t", entry_point="a.b:C", inputs=["eval:methods.toml"]).input_hashes()
    assert len(table["eval:methods.toml"]) == 64
    with pytest.raises(MethodError, match="is not a file"):
        Method("m", entry_point="a.b:C", inputs=[str(tmp_path / "missing.pt")]).input_hashes()
    with pytest.raises(MethodError, match="not installed"):
        Method("m", entry_point="a.b:C", inputs=["no_such_package_xyz:w.pt"]).input_hashes()


def test_a_method_with_a_missing_input_is_skipped_with_the_reason(tmp_path):
    method = Method("m", entry_point="sim_envs.agents:OracleAgent", inputs=[str(tmp_path / "gone.pt")])
    reason = check_available(method, build=False)
    assert reason is not None and "gone.pt" in reason and "is not a file" in reason


def test_network_methods_name_the_shipped_weights():
    methods = load_methods()
    for name in ("CNN-SLAM", "Laina", "raw-CNN", "focal-adjusted", "adjusted+refined"):
        assert methods[name].inputs == ("cnnslam:depthnet/weights/default.pt",)
        assert len(methods[name].input_hashes()) == 1


def test_a_seed_may_go_to_several_places():
    m = Method("m", entry_point="a:B", kwargs={"opts": {"k": 1}}, seed=["seed", "opts.draw"])
    assert m.seed_targets == ("seed", "opts.draw")
    assert m.agent_kwargs(4) == {"opts": {"k": 1, "draw": 4}, "seed": 4}
    with pytest.raises(MethodError, match="seed target"):
        Method("m", entry_point="a:B", seed=["ok", "not ok"])


def test_the_fingerprint_source_covers_the_agents_package_and_wrapped_agents(tmp_path, monkeypatch):
    package = tmp_path / "myagents"
    package.mkdir()
    (package / "__init__.py").write_text("")
    (package / "slam.py").write_text("class Slam: pass\n")
    (tmp_path / "single.py").write_text("class One: pass\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    m = Method("m", entry_point="myagents.slam:Slam")
    wrapped = Method("w", entry_point="sim_envs.agents:BiasedPoseAgent", kwargs={"agent": "single:One"})
    before, before_wrapped = m.source_hashes(), wrapped.source_hashes()
    assert set(before) == {"myagents"} and set(before_wrapped) == {"sim_envs", "single"}
    (package / "slam.py").write_text("class Slam:\n    x = 1\n")  # an edit anywhere in the package
    (tmp_path / "single.py").write_text("class One:\n    y = 2\n")
    import os

    for path in (package / "slam.py", tmp_path / "single.py"):  # a new mtime even on a coarse clock
        os.utime(path, ns=(path.stat().st_atime_ns, path.stat().st_mtime_ns + 10**9))
    assert m.source_hashes()["myagents"] != before["myagents"]
    assert wrapped.source_hashes()["single"] != before_wrapped["single"]
    assert wrapped.source_hashes()["sim_envs"] == before_wrapped["sim_envs"]
    assert external_method("X", tmp_path).source_hashes() == {}


def test_a_method_file_may_not_silently_replace_a_built_in_method(tmp_path):
    from eval.bench.methods import merge_methods

    base = load_methods()
    mine = {"CNN-SLAM": Method("CNN-SLAM", entry_point="a:B"), "Mine": Method("Mine", entry_point="a:C")}
    with pytest.raises(MethodError, match="redefines the method.*CNN-SLAM.*--override"):
        merge_methods(base, mine, "mine.toml")
    merged = merge_methods(base, mine, "mine.toml", override=True)
    assert merged["CNN-SLAM"].entry_point == "a:B" and "Mine" in merged and "ORB" in merged


def test_an_external_folder_declares_itself_in_method_toml(tmp_path):
    (tmp_path / "method.toml").write_text('sensor = "rgbd"\nuses_ground_truth = ["depth"]\nalign = "sim3"\n')
    m = external_method("RGBD-odo", tmp_path)
    assert (m.sensor, m.uses_ground_truth, m.align) == ("rgbd", ("depth",), "sim3")
    assert external_method("plain", tmp_path / "nothing-declared").sensor == "mono"
    (tmp_path / "method.toml").write_text('sensor = "lidar"\n')
    with pytest.raises(MethodError, match="sensor must be one of"):
        external_method("bad", tmp_path)
    (tmp_path / "method.toml").write_text('speed = "fast"\n')
    with pytest.raises(MethodError, match="unknown field"):
        external_method("bad", tmp_path)


def test_entry_point_problem_tells_a_broken_definition_from_a_missing_package(tmp_path, monkeypatch):
    """A module that is not there, a misspelt class or a module raising on import: broken (refused by a suite);
    an existing module that imports a package this machine lacks: optional (skipped where a suite brings it)."""
    from eval.bench.methods import entry_point_problem

    (tmp_path / "mymod.py").write_text("class MySlam:\n    pass\n")
    (tmp_path / "needs_dep.py").write_text("import no_such_dependency_pkg\nclass Agent:\n    pass\n")
    (tmp_path / "raises_on_import.py").write_text("raise RuntimeError('a bug at import')\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    assert entry_point_problem(Method("ok", entry_point="mymod:MySlam")) is None
    assert entry_point_problem(external_method("ext", tmp_path)) is None
    typo = entry_point_problem(Method("mine", entry_point="mymod:MySlma"))
    assert typo is not None and not typo.optional
    assert "module 'mymod' has no 'MySlma'" in typo.reason and "did you mean 'mymod:MySlam'?" in typo.reason
    for entry, words in (("nosuchmod:Agent", "no module 'nosuchmod'"), ("nosuchpkg.sub:Agent", "no module"),
                         ("raises_on_import:Agent", "RuntimeError: a bug at import")):  # fmt: skip
        problem = entry_point_problem(Method("m", entry_point=entry))
        assert problem is not None and not problem.optional and words in problem.reason, entry
    lacking = entry_point_problem(Method("dep", entry_point="needs_dep:Agent"))
    assert lacking is not None and lacking.optional and "no_such_dependency_pkg" in lacking.reason
    assert "\n" not in lacking.reason and "\n" not in typo.reason
