import pickle

import pytest

from sim_envs.errors import SimEnvError, UnknownNameError
from sim_envs.scenes.scenegen import TEST_STYLES, TRAIN_STYLES
from sim_envs.sequences import (
    TABLE1_SEQUENCES,
    TEST_SEED_LIMIT,
    TRAIN_SEED_BASE,
    SequenceSpec,
    get_sequence,
    gym_id,
    list_sequences,
    registered_names,
    rotation_stress_spec,
    training_specs,
)


def test_table1_analogues_have_the_papers_cameras_and_trajectories():
    tests = list_sequences("test")
    assert set(TABLE1_SEQUENCES) <= set(tests)
    for name in TABLE1_SEQUENCES:
        spec = get_sequence(name)
        if name.startswith(("office", "living")):
            assert spec.camera == "icl" and spec.trajectory == "handheld"
            assert spec.style == name[:-1]
        else:
            assert spec.camera == "tum_fr3"
    assert get_sequence("tum_long_office").trajectory == "loop"
    assert get_sequence("tum_nostructure_near").trajectory == "plane_near"
    assert get_sequence("tum_nostructure_near").params["loop"] is True
    assert get_sequence("tum_structure_far").trajectory == "far_structure"
    # as in ICL-NUIM, the sequences of one room share it and differ in trajectory
    offices = [get_sequence(f"office{i}") for i in range(3)]
    assert len({(s.style, s.scene_seed) for s in offices}) == 1
    assert len({(s.seed, s.params["speed"]) for s in offices}) == 3


def test_rotation_stress_sequences():
    for name, axes, speed in [
        ("rot_yaw_15", "yaw", 15.0),
        ("rot_yaw_30", "yaw", 30.0),
        ("rot_yaw_60", "yaw", 60.0),
        ("rot_pitch_30", "pitch", 30.0),
        ("rot_roll_30", "roll", 30.0),
        ("rot_rpy_30", "yaw+pitch+roll", 30.0),
    ]:
        spec = get_sequence(name)
        assert spec.trajectory == "rotation" and spec.camera == "tum_fr1" and spec.split == "test"
        assert spec.params == {"axes": axes, "speed_deg_s": speed}
    custom = rotation_stress_spec("pitch+yaw", 45, n_frames=300, amplitude_deg=20)
    assert custom.name == "rot_yaw-pitch_45" and custom.n_frames == 300
    assert custom.params == {"axes": "yaw+pitch", "speed_deg_s": 45.0, "amplitude_deg": 20.0}
    with pytest.raises(UnknownNameError):
        rotation_stress_spec("wobble", 30)


def test_lengths_are_20_to_60_seconds_at_30_hz():
    for name in list_sequences("all"):
        spec = get_sequence(name)
        assert spec.fps == 30.0 and 20.0 <= spec.duration_s <= 60.0, name


def test_test_and_training_splits_never_overlap():
    tests = [get_sequence(n) for n in list_sequences("test")]
    train = training_specs(200, seed=7) + [get_sequence(n) for n in list_sequences("train")]
    assert all(s.split == "test" and s.style in TEST_STYLES and s.scene_seed < TEST_SEED_LIMIT for s in tests)
    assert all(s.split == "train" and s.style in TRAIN_STYLES and s.scene_seed >= TRAIN_SEED_BASE for s in train)
    assert not {(s.style, s.scene_seed) for s in tests} & {(s.style, s.scene_seed) for s in train}
    assert not {s.camera for s in tests} & {s.camera for s in train}
    assert {s.camera for s in train} == {"nyu"}
    assert len({s.trajectory for s in train}) >= 4  # varied trajectories
    assert len({s.style for s in train}) == len(TRAIN_STYLES)


def test_training_specs_are_seeded():
    assert training_specs(5, seed=3) == training_specs(5, seed=3)
    assert training_specs(5, seed=3) != training_specs(5, seed=4)
    assert [s.name for s in training_specs(2, seed=3)] == ["train3_000", "train3_001"]
    assert list_sequences("train") == ["train_000", "train_001", "train_002"]
    assert [get_sequence(n) for n in list_sequences("train")] == training_specs(3, seed=0)


def test_registry_names_and_errors():
    assert registered_names() == list_sequences("all") == list_sequences("test") + list_sequences("train")
    with pytest.raises(UnknownNameError) as err:
        get_sequence("office9")
    for name in list_sequences("all"):
        assert name in str(err.value)
    with pytest.raises(SimEnvError, match="split"):
        list_sequences("validation")
    assert gym_id("office0") == "sim_envs/office0-v0" == get_sequence("office0").gym_id


def test_spec_validation_and_value_semantics():
    a = SequenceSpec("x", "office", 3, "handheld", {"speed": 0.2, "height_range": [1.1, 1.6]})
    b = SequenceSpec("x", "office", 3, "handheld", (("height_range", (1.1, 1.6)), ("speed", 0.2)))
    assert a == b and hash(a) == hash(b) and a.params == {"speed": 0.2, "height_range": (1.1, 1.6)}
    assert pickle.loads(pickle.dumps(a)) == a
    assert a.intrinsics().width == 320 and a.with_frames(10).n_frames == 10
    with pytest.raises(UnknownNameError, match="valid kinds"):
        SequenceSpec("x", "office", 3, "teleport")
    with pytest.raises(SimEnvError, match="valid: .*speed"):
        SequenceSpec("x", "office", 3, "handheld", {"velocity": 1.0})
    with pytest.raises(SimEnvError, match="fps"):
        SequenceSpec("x", "office", 3, "handheld", {"fps": 60.0})
    with pytest.raises(UnknownNameError, match="tum_fr1"):
        SequenceSpec("x", "office", 3, "handheld", camera="kinect9")
    with pytest.raises(SimEnvError, match="split"):
        SequenceSpec("x", "office", 3, "handheld", split="val")
    with pytest.raises(SimEnvError, match="n_frames"):
        SequenceSpec("x", "office", 3, "handheld", n_frames=1)
    with pytest.raises(SimEnvError, match="scene_seed"):
        SequenceSpec("x", "bedroom", 12, "handheld", split="train")


def test_variant_marks_name_lit_and_rich_rooms():
    from sim_envs.sequences import VARIANT_MARKS, split_variant, variant_spec

    assert VARIANT_MARKS == {"lit": ("lighting", "lit"), "rich": ("detail", "rich")}
    assert split_variant("office0+lit+rich") == ("office0+lit", "detail", "rich")
    assert split_variant("office0") is None and split_variant("office0+dark") is None
    office = get_sequence("office0")
    assert variant_spec("office0") is office and office.detail == "standard"
    for name in ("office0+lit+rich", "office0+rich+lit"):
        spec = variant_spec(name)
        assert (spec.name, spec.lighting, spec.detail, spec.trajectory) == (name, "lit", "rich", office.trajectory)
    assert variant_spec("living1+rich").detail == "rich" and variant_spec("living1+rich").lighting == "flat"
    with pytest.raises(SimEnvError, match="more than one detail mark"):
        variant_spec("office0+rich+rich")
    with pytest.raises(UnknownNameError, match=r"variant marks \+lit, \+rich"):
        variant_spec("office0+dark")
    with pytest.raises(SimEnvError, match="detail must be one of standard, rich"):
        SequenceSpec("x", "office", 3, "handheld", detail="cluttered")
