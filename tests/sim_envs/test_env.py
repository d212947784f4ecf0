import functools
import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from scipy.spatial.transform import Rotation

import sim_envs
from sim_envs.camera import Intrinsics
from sim_envs.env import SceneEnv, SlamEnv, relative_translation_error
from sim_envs.errors import SimEnvError, UnknownNameError
from sim_envs.frames import Frame
from sim_envs.sequences import list_sequences
from sim_envs.sources.simsource import FrameListSource

N = 6


def _source(n: int = N) -> FrameListSource:
    intr = Intrinsics(30.0, 31.0, 15.5, 11.5, 32, 24)
    rng = np.random.default_rng(1)
    frames = []
    for i in range(n):
        T = np.eye(4)
        T[:3, :3] = Rotation.from_euler("xz", [3.0 * i, -2.0 * i], degrees=True).as_matrix()
        T[:3, 3] = [0.04 * i, 0.02 * i**2, 1.0]
        frames.append(
            Frame(
                i,
                10.0 + i / 30,
                rng.integers(0, 256, (24, 32, 3), dtype=np.uint8),
                np.full((24, 32), 2.0, np.float32),
                T,
                labels=np.full((24, 32), 1, np.uint8),
                instances=np.full((24, 32), 3, np.int32),
            )
        )
    return FrameListSource("arrays", intr, frames)


def _gt_action(env: SlamEnv, k: int) -> dict:
    return {"T_world_cam": env.source.poses[k].copy(), "tracked": 1}


# --------------------------------------------------------------------------------------- spaces and episode flow


def test_spaces_and_observation_hold_only_what_a_monocular_camera_gives():
    env = SlamEnv(source=_source())
    assert set(env.observation_space.spaces) == {"rgb", "timestamp", "intrinsics"}
    assert env.observation_space["rgb"].shape == (24, 32, 3) and env.observation_space["rgb"].dtype == np.uint8
    assert env.action_space["T_world_cam"].shape == (4, 4) and env.action_space["tracked"].n == 2
    obs, info = env.reset(seed=0)
    assert obs in env.observation_space
    np.testing.assert_array_equal(obs["rgb"], env.source.frame(0).rgb)
    np.testing.assert_array_equal(obs["intrinsics"], [30.0, 31.0, 15.5, 11.5])
    assert obs["timestamp"][0] == pytest.approx(10.0)
    assert info["frame_index"] == 0 and set(info) == {"frame_index", "timestamp", "gt_T_world_cam"}
    np.testing.assert_array_equal(info["gt_T_world_cam"], env.source.poses[0])


def test_episode_runs_one_action_per_frame_and_terminates_after_the_last():
    env = SlamEnv(source=_source())
    env.reset()
    for k in range(N):
        obs, reward, terminated, truncated, info = env.step(_gt_action(env, k))
        assert reward == 0.0  # exact poses: no relative-pose error
        assert terminated == (k == N - 1) and not truncated
        expected = min(k + 1, N - 1)  # after the last frame the last observation is repeated
        assert info["frame_index"] == expected
        np.testing.assert_array_equal(obs["rgb"], env.source.frame(expected).rgb)
    with pytest.raises(SimEnvError, match="reset"):
        env.step(_gt_action(env, N - 1))
    with pytest.raises(SimEnvError, match="reset"):
        SlamEnv(source=_source()).step(_gt_action(env, 0))


def test_max_frames_truncates_and_time_limit_wrapper_works():
    env = SlamEnv(source=_source(), max_frames=3)
    env.reset()
    flags = [env.step(_gt_action(env, k))[2:4] for k in range(3)]
    assert flags == [(False, False), (False, False), (False, True)]
    wrapped = gym.make("sim_envs/Replay-v0", source=_source(), max_episode_steps=2)
    wrapped.reset()
    wrapped.step(_gt_action(wrapped.unwrapped, 0))
    assert wrapped.step(_gt_action(wrapped.unwrapped, 1))[3] is True


def test_reward_is_minus_the_relative_translation_error():
    env = SlamEnv(source=_source())
    env.reset()
    # the estimate lives in another world frame (any rigid transform): motions are unchanged, reward 0
    T_other_world = np.eye(4)
    T_other_world[:3, :3] = Rotation.from_rotvec([0.3, -1.0, 0.5]).as_matrix()
    T_other_world[:3, 3] = [5.0, -2.0, 7.0]
    rewards = [env.step({"T_world_cam": T_other_world @ env.source.poses[k], "tracked": 1})[1] for k in range(3)]
    assert rewards == pytest.approx([0.0, 0.0, 0.0], abs=1e-12)
    # a monocular estimate at twice the scale: the error of each motion is the motion's length
    env.reset()
    poses = env.source.poses
    rewards = []
    for k in range(3):
        T = poses[k].copy()
        T[:3, 3] *= 2.0
        rewards.append(env.step({"T_world_cam": T, "tracked": 1})[1])
    step_lengths = np.linalg.norm(np.diff(poses[:3, :3, 3], axis=0), axis=1)
    assert rewards[0] == 0.0
    assert rewards[1:] == pytest.approx(-step_lengths, rel=1e-12)
    assert relative_translation_error(poses[0], poses[1], poses[0], poses[1]) == 0.0


def test_full_ground_truth_by_argument_or_reset_option():
    env = SlamEnv(source=_source(), ground_truth="full")
    _, info = env.reset()
    assert info["gt_depth"].dtype == np.float32 and info["gt_labels"].dtype == np.uint8
    assert info["gt_instances"].dtype == np.int32 and info["gt_depth"].shape == (24, 32)
    env = SlamEnv(source=_source())
    assert "gt_depth" not in env.reset()[1]
    assert "gt_depth" in env.reset(options={"ground_truth": "full"})[1]
    assert "gt_depth" not in env.reset()[1]  # the option holds for one episode
    assert "sensor_depth" not in env.reset(options={"ground_truth": "full"})[1]  # no depth sensor: no key
    with pytest.raises(SimEnvError, match="ground_truth"):
        env.reset(options={"ground_truth": "all"})
    with pytest.raises(SimEnvError, match="unknown reset option"):
        env.reset(options={"start": 3})


def test_malformed_actions_and_arguments():
    env = SlamEnv(source=_source())
    env.reset()
    with pytest.raises(SimEnvError, match=r"frame 0: .*\(4, 4\)"):
        env.step({"T_world_cam": np.eye(3), "tracked": 1})
    with pytest.raises(SimEnvError, match="frame 0: .*dict"):
        env.step(np.eye(4))
    with pytest.raises(SimEnvError, match="exactly one"):
        SlamEnv()
    with pytest.raises(SimEnvError, match="exactly one"):
        SlamEnv("office0", source=_source())
    with pytest.raises(UnknownNameError) as err:
        SlamEnv("office7")
    assert "living2" in str(err.value)
    with pytest.raises(SimEnvError, match="renderer"):
        SlamEnv("office0", renderer="blender")
    with pytest.raises(SimEnvError, match="source="):
        gym.make("sim_envs/Replay-v0")
    with pytest.raises(SimEnvError, match="outside the test range"):
        SceneEnv(seed=5000)


def test_render_returns_the_current_image():
    env = SlamEnv(source=_source(), render_mode="rgb_array")
    obs, _ = env.reset()
    np.testing.assert_array_equal(env.render(), obs["rgb"])
    assert SlamEnv(source=_source()).render() is None


# ----------------------------------------------------------------------------------------- registered environments


def _make_kwargs(env_id: str) -> dict:
    if env_id == "sim_envs/Scene-v0":
        return {"style": "living", "seed": 2, "n_frames": 4, "trajectory": "rotation"}
    if env_id == "sim_envs/Replay-v0":
        return {"source": _source()}
    return {"max_frames": 4}


def test_every_sequence_has_an_id():
    expected = {"sim_envs/Scene-v0", "sim_envs/Replay-v0"} | {f"sim_envs/{n}-v0" for n in list_sequences("all")}
    assert set(sim_envs.ENV_IDS) == expected
    assert expected <= set(gym.registry)


@pytest.mark.parametrize("env_id", sim_envs.ENV_IDS)
def test_check_env_passes_for_every_registered_id(env_id):
    env = gym.make(env_id, **_make_kwargs(env_id))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env.unwrapped)
    # the only warnings allowed are about the unbounded pose / intrinsics / timestamp boxes
    unexpected = [str(w.message) for w in caught if "infinity" not in str(w.message)]
    assert unexpected == []
    env.close()


def test_simulated_env_is_deterministic_and_matches_its_source():
    a = gym.make("sim_envs/office0-v0", max_frames=3)
    b = gym.make("sim_envs/office0-v0", max_frames=3)
    obs_a, _ = a.reset(seed=1)
    obs_b, _ = b.reset(seed=2)
    np.testing.assert_array_equal(obs_a["rgb"], obs_b["rgb"])
    obs_a = a.step(_gt_action(a.unwrapped, 0))[0]
    np.testing.assert_array_equal(obs_a["rgb"], a.unwrapped.source.frame(1).rgb)
    assert obs_a["rgb"].std() > 5.0  # a textured room, not a blank image
    a.close()
    b.close()


def test_async_vector_env_with_spawned_workers():
    make = functools.partial(gym.make, "sim_envs:sim_envs/rot_yaw_30-v0", max_frames=3)
    single = make()
    obs0, _ = single.reset()
    expected_obs1 = single.unwrapped.source.frame(1).rgb
    poses = single.unwrapped.source.poses
    venv = gym.vector.AsyncVectorEnv([make, make], context="spawn")
    try:
        obs, info = venv.reset(seed=0)
        assert obs["rgb"].shape == (2, *obs0["rgb"].shape)
        np.testing.assert_array_equal(obs["rgb"][1], obs0["rgb"])
        action = {"T_world_cam": np.stack([poses[0], poses[0]]), "tracked": np.array([1, 1])}
        obs, reward, terminated, truncated, info = venv.step(action)
        np.testing.assert_array_equal(obs["rgb"][0], expected_obs1)
        np.testing.assert_array_equal(info["frame_index"], [1, 1])
        assert not terminated.any() and not truncated.any()
    finally:
        venv.close()
        single.close()


def test_replay_env_reads_a_tum_rgbd_folder(tmp_path):
    from sim_envs.folders.datasets import export_tum_rgbd

    source = _source()
    folder = export_tum_rgbd(source, tmp_path / "seq", progress=False)
    env = gym.make("sim_envs/Replay-v0", source=str(folder), ground_truth="full")
    obs, info = env.reset()
    assert env.unwrapped.source.intrinsics == source.intrinsics
    for k in range(N):
        np.testing.assert_array_equal(obs["rgb"], source.frame(k).rgb)
        np.testing.assert_allclose(info["gt_T_world_cam"], source.poses[k], atol=1e-5)
        np.testing.assert_allclose(info["gt_depth"], source.frame(k).depth, atol=1e-3)
        obs, _, terminated, _, info = env.step(_gt_action(env.unwrapped, k))
    assert terminated
    with pytest.raises(SimEnvError):
        gym.make("sim_envs/Replay-v0", source=str(tmp_path / "missing"))


def test_full_ground_truth_carries_the_depth_sensor_apart_from_the_exact_depth():
    base = _source()
    frames = [Frame(f.index, f.timestamp, f.rgb, f.depth, f.T_world_cam, labels=f.labels, instances=f.instances,
                    sensor_depth=np.where(np.arange(32) % 5 == 0, 0.0, 2.01).astype(np.float32)[None].repeat(24, 0))
              for f in (base.frame(i) for i in range(N))]  # fmt: skip
    env = SlamEnv(source=FrameListSource("arrays", base.intrinsics, frames), ground_truth="full")
    _, info = env.reset()
    assert info["sensor_depth"].dtype == np.float32 and info["sensor_depth"].shape == (24, 32)
    assert (info["sensor_depth"][:, 0] == 0).all() and info["sensor_depth"][0, 1] == pytest.approx(2.01)
    assert (info["gt_depth"] == 2.0).all()  # the judge's depth stays exact


def test_the_env_says_the_lens_distortion_of_the_images_it_delivers(tmp_path):
    from sim_envs.camera import preset
    from sim_envs.env import ReplayEnv
    from sim_envs.folders.datasets import RgbdFolder
    from sim_envs.folders.folder_exports import write_folder

    intr = preset("tum_fr1", 32, 24)
    frames = [Frame(i, 5.0 + i / 30, np.full((24, 32, 3), 9 * i, np.uint8), np.ones((24, 32), np.float32), np.eye(4))
              for i in range(2)]
    folder = write_folder(FrameListSource("x", intr, frames), tmp_path / "rgbd_dataset_freiburg1_x", "tum",
                          camera_file=False)  # named fr1: TUM's fr1 lens
    raw, undistorted = RgbdFolder(folder, undistort="none"), RgbdFolder(folder, size=(16, 12))
    np.testing.assert_array_equal(ReplayEnv(raw).distortion, raw.camera.distortion)  # left distorted: its lens
    assert raw.camera.distorted and not ReplayEnv(undistorted).distortion.any()  # undistorted: none left
    assert not SlamEnv(source=FrameListSource("x", intr, frames)).distortion.any()  # pinhole frames
    assert "distortion" not in ReplayEnv(raw).observation_space.spaces  # not part of the observation
