import logging

import gymnasium as gym
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import sim_envs  # noqa: F401  (registers the environments)
from sim_envs.agent import AgentOutput, KeyframeDepth, MapModel
from sim_envs.agents import ConstantPoseAgent, OracleAgent
from sim_envs.camera import Intrinsics
from sim_envs.driver import EpisodeResult, run_episode
from sim_envs.env import SlamEnv
from sim_envs.errors import SimEnvError
from sim_envs.frames import Frame
from sim_envs.sources.simsource import FrameListSource

N = 8


def _source(n: int = N) -> FrameListSource:
    intr = Intrinsics(30.0, 31.0, 15.5, 11.5, 32, 24)
    rng = np.random.default_rng(0)
    frames = []
    for i in range(n):
        T = np.eye(4)
        T[:3, :3] = Rotation.from_euler("y", 2.0 * i, degrees=True).as_matrix()
        T[:3, 3] = [0.05 * i, 0.0, 0.01 * i]
        frames.append(
            Frame(
                index=i,
                timestamp=100.0 + i / 30,
                rgb=rng.integers(0, 256, (24, 32, 3), dtype=np.uint8),
                depth=np.full((24, 32), 1.0 + 0.1 * i, np.float32),
                T_world_cam=T,
                labels=np.full((24, 32), i % 4, np.uint8),
                instances=np.full((24, 32), i, np.int32),
            )
        )
    return FrameListSource("arrays", intr, frames)


def test_oracle_episode_has_exact_poses_and_keyframe_ground_truth():
    env = SlamEnv(source=_source())
    result = run_episode(env, OracleAgent(keyframe_every=3), progress=False)
    assert isinstance(result, EpisodeResult)
    assert result.n_frames == N and result.sequence == "arrays" and result.agent == "oracle"
    assert result.uses_ground_truth and result.env_id is None
    np.testing.assert_array_equal(result.frame_indices, np.arange(N))
    np.testing.assert_allclose(result.timestamps, 100.0 + np.arange(N) / 30)
    np.testing.assert_array_equal(result.T_world_cam_est, result.T_world_cam_gt)
    np.testing.assert_array_equal(result.T_world_cam_gt, env.source.poses)
    assert result.tracked.all() and result.step_seconds.shape == (N,) and (result.step_seconds >= 0).all()
    # key-frames at frames 0, 3, 6 with ground-truth depth; keyframe_gt are the matching source frames
    assert [kf.timestamp for kf in result.keyframes] == pytest.approx(100.0 + np.array([0, 3, 6]) / 30)
    assert [f.index for f in result.keyframe_gt] == [0, 3, 6]
    for kf, gt in zip(result.keyframes, result.keyframe_gt, strict=True):
        np.testing.assert_array_equal(kf.depth, gt.depth)
    assert result.extras["frames"] == N and result.extras["finish_seconds"] >= 0


def test_constant_pose_agent_with_max_frames():
    result = run_episode(SlamEnv(source=_source()), ConstantPoseAgent(tracked=False), max_frames=5, progress=False)
    assert result.n_frames == 5 and not result.uses_ground_truth
    np.testing.assert_array_equal(result.T_world_cam_est, np.tile(np.eye(4), (5, 1, 1)))
    assert not result.tracked.any() and result.keyframes == [] and result.keyframe_gt == []
    np.testing.assert_array_equal(result.T_world_cam_gt, _source().poses[:5])


class _Scripted:
    """An agent whose step returns what a test scripts, to exercise the driver's checks."""

    def __init__(self, bad_step: int, bad_action: object, output: object = None) -> None:
        self.bad_step, self.bad_action, self.output = bad_step, bad_action, output
        self.n = 0

    def reset(self, intrinsics, image_size):
        self.n = 0

    def step(self, observation):
        self.n += 1
        if self.n - 1 == self.bad_step:
            return self.bad_action
        return {"T_world_cam": np.eye(4), "tracked": True}

    def finish(self):
        return self.output if self.output is not None else AgentOutput()


@pytest.mark.parametrize(
    ("action", "message"),
    [
        ({"T_world_cam": np.eye(3), "tracked": 1}, r"shape \(4, 4\)"),
        ({"T_world_cam": 2.0 * np.eye(4), "tracked": 1}, "not a rigid transform"),
        ({"T_world_cam": np.diag([1.0, 1.0, -1.0, 1.0]), "tracked": 1}, "not a rigid transform"),
        ({"T_world_cam": np.full((4, 4), np.nan), "tracked": 1}, "NaN"),
        ({"T_world_cam": np.eye(4), "tracked": 7}, "'tracked' must be 0 or 1"),
        ({"pose": np.eye(4)}, "must return a dict with 'T_world_cam'"),
        (np.eye(4), "must return a dict"),
    ],
)
def test_malformed_actions_are_named_by_step(action, message):
    env = SlamEnv(source=_source())
    with pytest.raises(SimEnvError, match=message) as err:
        run_episode(env, _Scripted(bad_step=4, bad_action=action), progress=False)
    assert "step 4 (frame 4)" in str(err.value)


def test_finish_may_return_a_dict_and_unmatched_keyframes_are_dropped(caplog):
    output = {
        "keyframes": [
            {"timestamp": 100.0 + 2 / 30, "depth": np.ones((24, 32), np.float32), "T_world_cam": np.eye(4)},
            KeyframeDepth(timestamp=55.0, depth=np.ones((24, 32), np.float32), T_world_cam=np.eye(4)),
        ],
        "extras": {"note": "x"},
    }
    with caplog.at_level(logging.WARNING, logger="sim_envs.driver"):
        result = run_episode(SlamEnv(source=_source()), _Scripted(-1, None, output), progress=False)
    assert len(result.keyframes) == 1 and result.keyframe_gt[0].index == 2
    assert result.extras["note"] == "x" and result.extras["unmatched_keyframes"] == [55.0]
    assert "match no frame" in caplog.text
    with pytest.raises(SimEnvError, match="unknown key"):
        run_episode(SlamEnv(source=_source()), _Scripted(-1, None, {"kf": []}), progress=False)


def test_finish_may_hand_back_a_global_model():
    points = np.random.default_rng(0).normal(size=(50, 3)).astype(np.float32)
    output = {"keyframes": [], "model": {"points": points, "labels": np.zeros(50, np.uint8)}}
    result = run_episode(SlamEnv(source=_source()), _Scripted(-1, None, output), progress=False)
    assert isinstance(result.model, MapModel) and len(result.model) == 50
    np.testing.assert_array_equal(result.model.points, points)
    for bad, message in (({"points": np.zeros((5, 2))}, "must be \\(N, 3\\)"),
                         ({"points": points, "labels": np.zeros(3)}, "one row per point"),
                         ({"vertices": points}, "not a valid MapModel")):
        with pytest.raises(SimEnvError, match=message):
            run_episode(SlamEnv(source=_source()), _Scripted(-1, None, {"model": bad}), progress=False)
    no_model = run_episode(SlamEnv(source=_source()), _Scripted(-1, None, {"keyframes": []}), progress=False)
    assert no_model.model is None


def test_ground_truth_agent_gets_full_ground_truth_from_a_pose_only_env():
    env = gym.make("sim_envs/Replay-v0", source=_source(), ground_truth="pose")
    result = run_episode(env, OracleAgent(keyframe_every=4), progress=False)
    assert result.env_id == "sim_envs/Replay-v0"
    assert len(result.keyframes) == 2  # frames 0 and 4: the env was asked for gt_depth although built with "pose"
    np.testing.assert_array_equal(result.keyframes[1].labels, result.keyframe_gt[1].labels)


def test_driver_rejects_non_slam_envs():
    with pytest.raises(SimEnvError, match="SlamEnv"):
        run_episode(gym.make("CartPole-v1"), ConstantPoseAgent(), progress=False)


def test_match_timestamp_takes_the_nearest_within_the_tolerance():
    from sim_envs.driver import KEYFRAME_TIME_TOLERANCE, match_timestamp

    stamps = np.array([0.0, 1 / 30, 2 / 30])
    assert match_timestamp(stamps, 1 / 30 + 0.5 * KEYFRAME_TIME_TOLERANCE) == 1
    assert match_timestamp(stamps, 1 / 30 + 2 * KEYFRAME_TIME_TOLERANCE) is None
    assert match_timestamp(np.array([]), 0.0) is None


class _OfflineAgent:
    """Answers the identity, untracked, at every step; at the end hands back poses for some frames: frames 0-4 with
    their true pose (frame 4 only filled in), one timestamp that matches no frame."""

    name = "offline"

    def __init__(self, poses: np.ndarray, stamps: np.ndarray) -> None:
        self._poses, self._stamps = poses, stamps

    def reset(self, intrinsics, image_size):
        pass

    def step(self, observation):
        return {"T_world_cam": np.eye(4), "tracked": 0}

    def finish(self):
        from sim_envs.agent import FinalTrajectory

        stamps = np.append(self._stamps[:5], 999.0)
        poses = np.concatenate([self._poses[:5], np.eye(4)[None]])
        return {"trajectory": FinalTrajectory(stamps, poses, tracked=np.array([1, 1, 1, 1, 0, 1], bool))}


def test_a_final_trajectory_replaces_the_per_step_answers_of_the_frames_it_names():
    source = _source()
    result = run_episode(SlamEnv(source=source), _OfflineAgent(source.poses, 100.0 + np.arange(N) / 30),
                         progress=False)  # fmt: skip
    np.testing.assert_array_equal(result.T_world_cam_est[:5], source.poses[:5])
    np.testing.assert_array_equal(result.T_world_cam_est[5:], np.broadcast_to(np.eye(4), (N - 5, 4, 4)))
    assert result.tracked.tolist() == [True] * 4 + [False] * (N - 4)  # frame 4 filled in, 5.. not named
    assert result.extras["final_trajectory"] == {"poses": 6, "frames_matched": 5, "unmatched_timestamps": [999.0]}


def test_a_bad_final_trajectory_gets_one_clear_error():
    from sim_envs.agent import FinalTrajectory

    with pytest.raises(SimEnvError, match=r"timestamps \(M,\) and T_world_cam \(M, 4, 4\)"):
        FinalTrajectory(np.zeros(3), np.zeros((2, 4, 4)))
    with pytest.raises(SimEnvError, match="tracked must be"):
        FinalTrajectory(np.zeros(1), np.eye(4)[None], tracked=np.ones(2, bool))
    source = _source()
    bad = np.eye(4)
    bad[:3, :3] *= 2.0  # not a rotation
    agent = _OfflineAgent(np.stack([bad] * N), 100.0 + np.arange(N) / 30)
    with pytest.raises(SimEnvError, match="not a rigid transform"):
        run_episode(SlamEnv(source=source), agent, progress=False)


class _Lens:
    """A source wrapper whose images carry a lens distortion (as a folder left distorted does)."""

    def __init__(self, source, distortion):
        self._source, self.distortion = source, distortion

    def __getattr__(self, name):
        return getattr(self._source, name)

    def __len__(self):
        return len(self._source)


class _Recorder(ConstantPoseAgent):
    def reset(self, *args, **kwargs):
        self.given = (args, kwargs)
        super().reset(*args)


class _Undistorter(_Recorder):
    takes_distortion = True


def test_only_an_agent_that_takes_the_distortion_is_given_it():
    coeffs = (0.26, -0.95, -0.005, 0.003, 1.16)
    env = SlamEnv(source=_Lens(_source(3), coeffs))
    np.testing.assert_array_equal(env.distortion, coeffs)
    plain, undistorter = _Recorder(), _Undistorter()
    run_episode(env, plain, progress=False)
    run_episode(env, undistorter, progress=False)
    assert plain.given[1] == {} and len(plain.given[0]) == 2  # the contract as it was: reset(intrinsics, size)
    assert undistorter.given[0][1] == (24, 32) and undistorter.given[1]["distortion"].dtype == np.float64
    np.testing.assert_array_equal(undistorter.given[1]["distortion"], coeffs)
    run_episode(SlamEnv(source=_source(3)), undistorter, progress=False)  # a pinhole source: zeros
    np.testing.assert_array_equal(undistorter.given[1]["distortion"], np.zeros(5))
    with pytest.raises(SimEnvError, match="5 finite coefficients"):
        SlamEnv(source=_Lens(_source(3), (0.1, 0.2)))
