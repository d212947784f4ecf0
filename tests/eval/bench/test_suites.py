"""Suite definitions, sequence references and their environments, the sweep's variants, the rotation share."""

from dataclasses import replace

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from eval.bench.methods import load_methods
from eval.bench.sequence_ref import REPLAY_ENV_ID, SequenceRef
from eval.bench.sequence_resolve import resolve_sequence
from eval.bench.suites import CAMERA_EFFECT_STRENGTHS, FOCAL_RATIOS, SUITES, Suite, get_suite, sweep_sequences
from eval.errors import SuiteError
from sim_envs.camera import camera_presets, preset
from sim_envs.sequences import TABLE1_SEQUENCES, get_sequence


def test_the_suites_of_the_issue():
    assert set(SUITES) == {"table1", "rotation", "ablation", "sweep", "depth_quality", "perf", "real", "transfer",
                           "lengths", "preprocessing", "quick"}
    table1 = get_suite("table1")
    # every suite sees its simulated sequences through the default camera, kinect
    assert tuple(s.name for s in table1.sequences) == tuple(f"{n}@kinect" for n in TABLE1_SEQUENCES)
    assert all(s.spec().camera_effects == "kinect" and s.base == s.name.split("@")[0] for s in table1.sequences)
    assert table1.methods == ("CNN-SLAM", "LSD-BS", "LSD", "ORB", "Laina", "REMODE", "ORB-SLAM3", "oracle")
    clean = table1.select(camera="clean")
    assert all(s.registered and s.env_id == f"sim_envs/{s.name}-v0" for s in clean.sequences)
    rotation = get_suite("rotation")
    assert [s.name for s in rotation.sequences][:3] == ["rot_yaw_15@kinect", "rot_yaw_30@kinect", "rot_yaw_60@kinect"]
    assert {s.name for s in rotation.sequences} >= {"rot_pitch_60@kinect", "rot_roll_15@kinect", "rot_rpy_30@kinect"}
    assert get_suite("ablation").methods == ("raw-CNN", "focal-adjusted", "adjusted+refined")
    assert get_suite("perf").kind == "perf" and not get_suite("perf").sequences
    quality = get_suite("depth_quality")
    assert [s.name for s in quality.sequences] == [f"{n}@kinect" for n in ("office0", "office1", "office2", "living0",
                                                                           "living1", "living2")]
    assert quality.frames is None and quality.methods[:2] == ("CNN-SLAM", "raw-CNN")
    methods = load_methods()
    assert all(methods[m].entry_point == "cnnslam.agent:GroundTruthAidedAgent" for m in quality.methods[2:])
    quick = get_suite("quick")
    assert "constant-pose" in quick.methods and set(table1.methods) - {"ORB-SLAM3"} <= set(quick.methods)
    assert quick.frames is not None and quick.frames <= 100
    with pytest.raises(SuiteError, match="valid suites: table1"):
        get_suite("tabel1")


def test_selecting_and_resolving_sequences():
    suite = get_suite("table1").select(["office1", "rot_yaw_45"], ["oracle"], frames=12, seeds=[1, 2])
    assert [s.name for s in suite.sequences] == ["office1@kinect", "rot_yaw_45@kinect"]  # the default camera
    named = get_suite("table1").select(["office1@clean", "office1@hard", "rot_yaw_45@clean"])
    assert [s.name for s in named.sequences] == ["office1", "office1@hard", "rot_yaw_45"]
    assert named.sequences[1].spec().camera_effects == "hard" and named.sequences[0].registered
    assert suite.methods == ("oracle",) and suite.frames == 12 and suite.seeds == (1, 2)
    rot = resolve_sequence("rot_yaw_45")
    assert rot.rotation == ("yaw", 45.0) and not rot.registered and rot.env_id == REPLAY_ENV_ID
    spec = rot.spec()
    assert spec.name == "rot_yaw_45" and spec.params == {"axes": "yaw", "speed_deg_s": 45.0}
    assert resolve_sequence("rot_yaw-pitch_20").spec().params["axes"] == "yaw+pitch"
    assert resolve_sequence("rot_rpy_30").registered  # the registered one, by its Gymnasium id
    with pytest.raises(SuiteError, match="valid: office0"):
        resolve_sequence("office9")
    with pytest.raises(SuiteError, match="frames must be >= 2"):
        get_suite("quick").select(frames=1)
    with pytest.raises(SuiteError, match="exactly one of base"):
        SequenceRef("x")
    with pytest.raises(SuiteError, match="not SequenceSpec fields"):
        SequenceRef("x", base="office0", overrides={"colour": 1})


def test_sweep_variants_change_one_thing_each():
    refs = sweep_sequences("office1")
    axes = {r.axis for r in refs}
    assert axes == {"texture", "rotation", "focal", "noise", "blur", "exposure", "rolling_shutter", "distortion"}
    base = get_sequence("office1")
    for ref in refs:
        spec = ref.spec()
        assert spec.name == ref.name and ref.env_id == REPLAY_ENV_ID
        changed = {k for k in base.__dataclass_fields__ if getattr(spec, k) != getattr(base, k)} - {"name"}
        assert changed <= {"texture_density", "camera_effects"}
        if ref.axis in CAMERA_EFFECT_STRENGTHS:  # one effect alone, on the clean camera
            assert changed == {"camera_effects"} and spec.camera_effects == f"{ref.axis}:{ref.axis_value:g}"
            assert spec.camera_effects_model().name == spec.camera_effects
        else:  # the other axes through the default camera
            assert spec.camera_effects == "kinect" and ref.name.endswith("@kinect")
        if ref.axis == "texture":
            assert spec.texture_density == ref.axis_value and ref.focal_ratio is None
    assert [r.axis_value for r in refs if r.axis == "focal"] == list(FOCAL_RATIOS)


def test_a_variant_environment_renders_with_its_camera():
    ref = SequenceRef("office1@focal1.4", base="office1", focal_ratio=1.4)
    env = ref.make_env(max_frames=2)
    try:
        obs, _ = env.reset()
        nyu = preset("nyu", 320, 240)
        assert obs["intrinsics"][0] == pytest.approx(1.4 * nyu.fx) and obs["rgb"].shape == (240, 320, 3)
        assert env.unwrapped.source.name == "office1@focal1.4"
    finally:
        env.close()


def test_a_camera_preset_applies_to_simulated_sequences_and_a_calibration_to_folders():
    kinect = get_suite("table1").select(["office0", "living1"], camera="kinect")
    assert [r.name for r in kinect.sequences] == ["office0@kinect", "living1@kinect"]
    spec = kinect.sequences[0].spec()
    assert spec.camera_effects == "kinect" and spec.trajectory == get_sequence("office0").trajectory
    assert kinect.sequences[0].describe()["overrides"] == {"camera_effects": "kinect"}  # in the fingerprint
    assert get_suite("table1").select(["office0"], camera="clean").sequences[0].name == "office0"  # today's bytes
    rot = get_suite("rotation").select(["rot_yaw_30"], camera="hard").sequences[0]
    assert rot.name == "rot_yaw_30@hard" and rot.spec().camera_effects == "hard"
    with pytest.raises(SuiteError, match="camera-effects presets of simulated sequences: clean, fr1, hard, kinect"):
        SequenceRef("office0", base="office0").with_camera_effects("kinnect")
    with pytest.raises(SuiteError, match="unknown camera preset 'tum_fr1' for simulated sequences; valid presets: "
                                         "clean, fr1, hard, kinect"):
        get_suite("table1").select(["office0"], camera="tum_fr1")  # a folder calibration on a simulated sequence


def test_a_lit_sequence_is_named_with_plus_lit_before_its_camera_and_fingerprinted():
    lit = get_suite("table1").select(["office0+lit", "living1@hard+lit"]).sequences  # the default camera: kinect
    assert [r.name for r in lit] == ["office0+lit@kinect", "living1+lit@hard"]
    assert lit[0].describe()["overrides"] == {"camera_effects": "kinect", "lighting": "lit"}
    spec = lit[1].spec()
    assert (spec.lighting, spec.camera_effects, spec.trajectory) == ("lit", "hard", get_sequence("living1").trajectory)
    assert resolve_sequence("rot_yaw_30+lit").spec().lighting == "lit"
    assert lit[0].with_lighting("flat").name == "office0@kinect"
    with pytest.raises(SuiteError, match="unknown lighting 'dark'; valid: flat, lit"):
        lit[0].with_lighting("dark")


def test_a_rich_sequence_is_named_with_plus_rich_after_its_lighting_and_round_trips():
    rich = get_suite("table1").select(["office0+rich", "living1+rich+lit@hard"]).sequences  # default camera: kinect
    assert [r.name for r in rich] == ["office0+rich@kinect", "living1+lit+rich@hard"]
    assert rich[0].describe()["overrides"] == {"camera_effects": "kinect", "detail": "rich"}
    spec = rich[1].spec()
    assert (spec.detail, spec.lighting, spec.camera_effects) == ("rich", "lit", "hard")
    assert spec.trajectory == get_sequence("living1").trajectory
    for ref in (*rich, resolve_sequence("rot_yaw_30+rich"), resolve_sequence("office0+lit+rich")):
        assert resolve_sequence(ref.name) == ref and not ref.registered
    assert rich[1].with_lighting("flat").name == "living1+rich@hard"
    assert rich[1].with_detail("standard").name == "living1+lit@hard"
    assert rich[1].with_lighting("flat").with_detail("standard").overrides == (("camera_effects", "hard"),)
    with pytest.raises(SuiteError, match="unknown detail 'cluttered'; valid: standard, rich"):
        rich[0].with_detail("cluttered")
    with pytest.raises(SuiteError, match="more than one lighting mark"):  # parsed as variant_spec parses it
        resolve_sequence("office0+lit+lit")


def test_camera_preset_names_do_not_collide_with_folder_calibrations():
    from eval.bench.sequence_ref import sim_camera_presets

    assert not set(sim_camera_presets()) & set(camera_presets())


def test_the_transfer_suite_compares_like_with_like(tmp_path):
    from eval.bench.sequence_ref import folder_ref
    from eval.bench.suites import BENCH_FRAMES, transfer_parts
    from sim_envs.folders.datasets import export_tum_rgbd
    from sim_envs.sources.simsource import SimulatedSequence

    folder = tmp_path / "realish"
    export_tum_rgbd(SimulatedSequence(get_sequence("office0")), folder, max_frames=25)
    suite = get_suite("transfer").select(sequences=[str(folder)])
    assert suite.frames == BENCH_FRAMES
    parts = transfer_parts(replace(suite, frames=10), ("kinect", "kinect+lit"))
    # per length: each simulated domain, its like-for-like null (as many windows per simulated sequence as the real
    # recording gives: 2 here), then the real folder; whole sequences need no windows
    assert [(p.length, p.suite.name) for p in parts] == [(10, "table1")] * 4 + [(10, "real"), (None, "table1"),
                                                                                 (None, "table1"), (None, "real")]
    assert [r.name for r in parts[2].suite.sequences][:2] == ["office0+lit@kinect", "office1+lit@kinect"]
    assert parts[0].suite.sequences[0].name == "office0@kinect"  # table1's own runs
    assert parts[0].suite.frames == 10 and parts[5].suite.frames is None
    assert {d for _, d in parts[0].domains} == {"sim:kinect"} and {d for _, d in parts[2].domains} == {"sim:kinect+lit"}
    null = parts[1].suite.sequences
    assert [(w.name, w.start) for w in null[:2]] == [("office0@kinect", 0), ("office0@kinect.from10", 10)]
    assert len(null) == 2 * len(parts[0].suite.sequences) and {d for _, d in parts[1].domains} == {"win:kinect"}
    windows = parts[4].suite.sequences  # 25 frames: two windows of 10, the remainder left out
    assert [(w.name, w.start) for w in windows] == [("realish", 0), ("realish.from10", 10)]  # the first: the same runs
    assert dict(parts[4].domains) == {"realish": "real:realish", "realish.from10": "real:realish"}
    assert [r.name for r in parts[7].suite.sequences] == ["realish"] and parts[7].domain_of("realish") == "real:realish"
    assert folder_ref(folder) == windows[0]  # the first window is the whole sequence on its first frames
    assert [p.length for p in transfer_parts(replace(suite, frames=None))] == [None, None]
    rich = transfer_parts(replace(suite, frames=None), ("kinect+rich", "kinect+rich+lit"))
    assert [r.name for r in rich[0].suite.sequences][:1] == ["office0+rich@kinect"]
    assert [r.name for r in rich[1].suite.sequences][:1] == ["office0+lit+rich@kinect"]
    assert {d for _, d in rich[1].domains} == {"sim:kinect+rich+lit"}
    with pytest.raises(SuiteError, match="unknown simulated domain 'kinect\\+dark'"):
        transfer_parts(get_suite("transfer"), ("kinect+dark",))


def test_a_window_is_the_frames_of_the_whole_from_its_start(tmp_path):
    from eval.bench.sequence_ref import folder_ref, window_refs
    from sim_envs.folders.datasets import export_tum_rgbd
    from sim_envs.sources.simsource import SimulatedSequence

    folder = tmp_path / "seq"
    export_tum_rgbd(SimulatedSequence(get_sequence("office0")), folder, max_frames=12)
    whole = folder_ref(folder)
    windows = window_refs(whole, 5)
    assert [w.start for w in windows] == [0, 5]  # 12 frames: 0-4, 5-9; 10-11 left out
    src, win = whole.make_source(), windows[1].make_source()
    assert len(win) == 7 and win.name == "seq.from5"
    np.testing.assert_array_equal(win.timestamps, src.timestamps[5:])
    np.testing.assert_array_equal(win.poses, src.poses[5:])
    a, b = src.frame(7), win.frame(2)
    assert b.index == 2 and b.timestamp == a.timestamp
    np.testing.assert_array_equal(a.rgb, b.rgb)
    np.testing.assert_array_equal(a.depth, b.depth)
    # the per-frame readers too: the env reads rgb() alone when it hands out no ground truth (it once read frame i's
    # image of the whole with frame start + i's pose)
    np.testing.assert_array_equal(win.rgb(2), a.rgb)
    np.testing.assert_array_equal(win.depth(2), src.depth(7))
    env = windows[1].make_env()
    obs, info = env.reset()
    for _ in range(2):
        obs, _, _, _, info = env.step({"T_world_cam": np.eye(4), "tracked": 0})
    np.testing.assert_array_equal(obs["rgb"], a.rgb)
    np.testing.assert_array_equal(info["gt_T_world_cam"], src.poses[7])
    env.close()
    with pytest.raises(IndexError):
        win.rgb(7)
    assert windows[1].describe()["window"] == "cnnslam-window/2" and "start" not in whole.describe()
    with pytest.raises(SuiteError, match="start must be a frame index >= 0"):
        replace(whole, start=-1)
    with pytest.raises(SuiteError, match="already a window"):
        window_refs(windows[1], 2)
    sim = window_refs(SequenceRef("office0", base="office0"), 700)
    assert [w.start for w in sim] == [0, 700] and not sim[1].registered and sim[1].env_id == REPLAY_ENV_ID


def test_undistortion_of_folder_sequences_gets_its_own_name_and_fingerprint(tmp_path):
    from eval.bench.sequence_ref import folder_ref
    from sim_envs.folders.datasets import export_tum_rgbd
    from sim_envs.sources.simsource import SimulatedSequence

    folder = tmp_path / "seq"
    export_tum_rgbd(SimulatedSequence(get_sequence("office0")), folder, max_frames=3)
    ref = folder_ref(folder)
    full = ref.with_folder_options(undistort="full")
    assert full.name == "seq~undistort_full" and full.undistort == "full" and full.describe()["undistort"] == "full"
    assert "undistort" not in ref.describe()  # the default leaves earlier runs' fingerprints as they were
    assert full.with_folder_options(undistort="none").name == "seq~undistort_none"
    assert full.with_folder_options(undistort="crop") == ref
    suite = get_suite("table1").select(sequences=[str(folder)], undistort="none")
    assert [s.name for s in suite.sequences] == ["seq~undistort_none"]
    with pytest.raises(SuiteError, match="--undistort applies to folder sequences"):
        get_suite("table1").select(undistort="full")
    with pytest.raises(SuiteError, match="other than crop only for a folder"):
        SequenceRef("office0", base="office0", undistort="full")


def test_a_recorded_motion_replays_in_the_same_room(tmp_path):
    from eval.bench.suites import transfer_parts

    t = np.arange(0.0, 10.0, 0.01)
    motion = tmp_path / "desk motion.txt"  # a slow pan with a small sideways drift, as a TUM file
    q = Rotation.from_euler("y", (5.0 * t)[:, None], degrees=True).as_quat()
    np.savetxt(motion, np.column_stack([t, 0.01 * t, 0 * t, 0 * t, q]), fmt="%.9f")
    ref = get_suite("table1").sequences[0].with_motion(motion)
    assert ref.name == "office0~desk_motion@kinect" and ref.spec().trajectory == "replay"
    assert ref.spec().camera_effects == "kinect" and ref.spec().scene_seed == get_sequence("office0").scene_seed
    short = SequenceRef("office0", base="office0", overrides={"n_frames": 30}).with_motion(motion, "desk")
    source = short.make_source()
    rel = np.linalg.inv(source.poses[0]) @ source.poses[-1]
    assert Rotation.from_matrix(rel[:3, :3]).magnitude() == pytest.approx(np.radians(5.0 * 29 / 30), abs=1e-6)
    transfer = get_suite("transfer")
    parts = transfer_parts(transfer, lengths=(20,), motions=[motion])
    # a real folder that is here (the kitchen in ../shared) gives many 20-frame windows: the simulated null
    # (win:kinect) comes before the motion's domain; without one there is no null and the real part is empty
    null = [["win:kinect"]] if transfer.sequences else []
    assert [sorted({d for _, d in p.domains}) for p in parts] == [["sim:kinect"], *null, ["sim:kinect~desk_motion"],
                                                                  sorted({d for _, d in parts[-1].domains})]
    moved = next(p for p in parts if p.domains and p.domains[0][1] == "sim:kinect~desk_motion")
    with pytest.raises(SuiteError, match="is not a file"):
        ref.with_motion(tmp_path / "nope.txt")
    assert ref.with_motion(motion).spec().n_frames == 300  # 10 s recorded: 1500 frames cut to what it covers
    assert ref.with_motion(motion, frames=200).spec().n_frames == 200  # and to what a suite runs: a path to fit
    assert moved.suite.sequences[0].spec().n_frames == 20
    described = ref.describe()
    assert len(described["motion_sha256"]) == 64  # an edited recording reruns
    (tmp_path / "a").mkdir(), (tmp_path / "b").mkdir()
    first, second = tmp_path / "a" / "groundtruth.txt", tmp_path / "b" / "groundtruth.txt"
    first.write_text(motion.read_text()), second.write_text(motion.read_text())
    assert get_suite("table1").sequences[0].with_motion(first).name == "office0~a@kinect"  # TUM's file name: its folder
    with pytest.raises(SuiteError, match="give the same name"):
        transfer_parts(get_suite("transfer"), lengths=(20,), motions=[first, first])


def test_a_suite_carries_its_report_gate_and_baseline_and_nothing_switches_on_its_name():
    import ast
    from pathlib import Path

    from eval.bench.suites import REPORT_LAYOUTS, SUITES
    from eval.reports.suite_reports import REPORTS

    assert set(REPORTS) == set(REPORT_LAYOUTS)
    assert [s.name for s in SUITES.values() if s.gated] == ["quick"]
    root = Path(__file__).resolve().parents[3]  # the repository, not the working directory
    assert SUITES["quick"].baseline_path == root / "results" / "baselines" / "quick.json"
    assert {s.name for s in SUITES.values() if s.real_folders} == {"real", "transfer", "preprocessing"}
    with pytest.raises(SuiteError, match="report must be one of"):
        Suite("x", "a suite with a report nobody writes", report="table2")
    # no comparison of a suite's name with a literal outside the registry
    names = set(SUITES)
    root = Path(__file__).resolve().parents[3]
    offenders = []
    for path in sorted((root / "eval").rglob("*.py")):
        if path.name == "suites.py":
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Compare) and any(
                    isinstance(side, ast.Attribute) and side.attr == "name" for side in [node.left, *node.comparators]):
                literals = [c.value for c in ast.walk(node) if isinstance(c, ast.Constant) and isinstance(c.value, str)]
                if names & set(literals):
                    offenders.append(f"{path.name}:{node.lineno}")
    assert not offenders


def _two_real_recordings(tmp_path, shared_data):
    """A dataset list naming the 7-Scenes kitchen and TUM fr1/desk (skipped where ../shared lacks them)."""
    kitchen = shared_data("data/real/7scenes_redkitchen")
    desk = shared_data("data/real/rgbd_dataset_freiburg1_desk", "groundtruth.txt", "rgb.txt")
    listing = tmp_path / "datasets.toml"
    listing.write_text(f'[datasets]\nredkitchen = "{kitchen}"\nfr1_desk = "{desk}"\n')
    return listing


def test_the_transfer_suite_sets_kinect_and_fr1_against_both_real_recordings(tmp_path, shared_data):
    from eval.bench.suites import transfer_parts, with_real_folders
    from sim_envs.sequences import FR1_MOTION_SEQUENCES

    suite = with_real_folders(get_suite("transfer"), _two_real_recordings(tmp_path, shared_data))
    assert [r.name for r in suite.sequences] == ["redkitchen", "fr1_desk"] and not suite.skipped
    parts = transfer_parts(replace(suite, frames=None), ("kinect", "fr1"))
    assert [sorted({d for _, d in p.domains}) for p in parts] == [["sim:kinect"], ["sim:fr1"],
                                                                  ["real:fr1_desk", "real:redkitchen"]]
    assert parts[1].suite.sequences[0].name == "office0@fr1" and parts[1].suite.sequences[0].spec().camera_effects \
        == "fr1"  # fmt: skip
    moved = transfer_parts(replace(suite, frames=None), ("fr1",), sim_sequences=FR1_MOTION_SEQUENCES)
    assert [r.name for r in moved[0].suite.sequences] == ["office_fr1motion@fr1", "living_fr1motion@fr1"]
    assert moved[0].suite.sequences[0].spec().trajectory == "handheld_stats"


@pytest.mark.slow
def test_transfer_report_smoke_two_presets_two_real_recordings_few_frames(tmp_path, shared_data):
    # a tiny transfer run: 2 methods, 4 frames, one fr1-motion sequence through kinect and fr1, the two real
    # recordings' first 4 frames; the report names both presets and both recordings
    from eval.bench import BenchOptions, run_bench
    from eval.bench.suites import TransferPart, transfer_parts, with_real_folders
    from eval.reports.transfer_report import report_transfer

    suite = with_real_folders(get_suite("transfer"), _two_real_recordings(tmp_path, shared_data))
    planned = transfer_parts(replace(suite, frames=None), ("kinect", "fr1"), sim_sequences=["office_fr1motion"])
    methods = ("constant-pose", "oracle")
    done = []
    for part in planned:
        small = replace(part.suite, methods=methods, seeds=(0,), frames=4)
        options = BenchOptions(frames=4, out=tmp_path / "runs", results=tmp_path / "results" / small.name,
                               progress=False, plots=False)  # fmt: skip
        outcome = run_bench(small, methods, options)
        assert outcome.exit_status == 0, outcome.rows
        done.append((TransferPart(4, small, part.domains), outcome.parts[0][1]))
    files = report_transfer(done, tmp_path / "report", "smoke")
    text = (tmp_path / "report" / "transfer.md").read_text()
    for domain in ("sim:kinect", "sim:fr1", "real:redkitchen", "real:fr1_desk"):
        assert domain in text
    assert any(f.name == "transfer.csv" for f in files)
