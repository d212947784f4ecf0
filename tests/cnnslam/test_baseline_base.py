"""cnnslam.baselines.base: the shell the baselines share (reset's checks, step's record, finish's guard)."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from cnnslam.baselines.base import BaselineAgent, checked_image_size, checked_intrinsics
from cnnslam.baselines.laina import LainaAgent
from cnnslam.baselines.orb import OrbSlamAgent
from cnnslam.baselines.remode import RemodeAgent
from cnnslam.errors import CnnSlamError
from sim_envs.agent import Agent, AgentOutput

K = np.array([240.0, 240.0, 159.5, 119.5])


class _Walker(BaselineAgent):
    """Moves 1 cm along x a frame; lost on odd frames; remembers what the hooks were given."""

    name = "walker"

    def _start(self, intrinsics: np.ndarray, image_size: tuple[int, int]) -> None:
        self.started_with = (intrinsics.copy(), image_size)
        self.infos: list[Any] = []

    def _track(self, observation: dict[str, np.ndarray], timestamp: float,
               info: dict[str, Any] | None) -> tuple[np.ndarray, bool]:
        self.infos.append(info)
        T = np.eye(4)
        T[0, 3] = 0.01 * len(self._tracked)
        return T, len(self._tracked) % 2 == 0

    def _finish(self) -> AgentOutput:
        return AgentOutput(extras=self.episode_extras())


def _obs(t: float, size: tuple[int, int] = (6, 8)) -> dict[str, np.ndarray]:
    return {"rgb": np.zeros((*size, 3), np.uint8), "timestamp": np.array([t])}


def test_the_shell_checks_records_and_answers() -> None:
    agent = _Walker()
    assert isinstance(agent, Agent)
    with pytest.raises(CnnSlamError, match=r"call reset\(intrinsics, image_size\) before step\(\)"):
        agent.step(_obs(0.0))
    with pytest.raises(CnnSlamError, match=r"finish\(\) before reset\(\)"):
        agent.finish()
    agent.reset(K.tolist(), (np.int64(6), 8))
    k, size = agent.started_with
    assert k.dtype == np.float64 and k.tolist() == K.tolist() and size == (6, 8) and type(size[0]) is int
    answers = [agent.step(_obs(0.1 * i), {"gt": i}) for i in range(3)]
    assert [a["tracked"] for a in answers] == [1, 0, 1] and [a["T_world_cam"][0, 3] for a in answers] == [0, .01, .02]
    assert agent._timestamps == [0.0, 0.1, 0.2] and agent.infos == [{"gt": 0}, {"gt": 1}, {"gt": 2}]
    assert agent.finish().extras == {"frames": 3, "tracked_share": 2 / 3}
    with pytest.raises(CnnSlamError, match=r"frame of size \(3, 4\) but the agent was reset for \(6, 8\)"):
        agent.step(_obs(0.3, (3, 4)))
    agent.reset(K, (6, 8))  # a new episode forgets the last one
    assert agent.finish().extras == {"frames": 0, "tracked_share": 0.0} and agent._poses == []


@pytest.mark.parametrize("bad", [[240.0, 240.0, 159.5], [0.0, 240.0, 159.5, 119.5], [np.nan, 1.0, 1.0, 1.0]])
def test_bad_intrinsics_are_refused_in_one_line(bad: list[float]) -> None:
    with pytest.raises(CnnSlamError, match=r"intrinsics must be \[fx, fy, cx, cy\] with positive focal lengths"):
        checked_intrinsics(bad)
    agent = _Walker()
    with pytest.raises(CnnSlamError):
        agent.reset(bad, (6, 8))
    with pytest.raises(CnnSlamError, match="before step"):  # no episode started
        agent.step(_obs(0.0))


@pytest.mark.parametrize("bad", [(0, 8), (6,), "ab", None])
def test_bad_image_sizes_are_refused(bad: Any) -> None:
    with pytest.raises(CnnSlamError, match="image_size must be"):
        checked_image_size(bad)


def test_a_baseline_without_its_hooks_cannot_be_built() -> None:
    class Half(BaselineAgent):
        def _start(self, intrinsics: np.ndarray, image_size: tuple[int, int]) -> None:
            pass

    with pytest.raises(TypeError, match="abstract"):
        Half()  # type: ignore[abstract]


def test_the_paper_baselines_are_built_on_the_shell() -> None:
    for cls, name in ((OrbSlamAgent, "orb_slam"), (LainaAgent, "laina"), (RemodeAgent, "remode")):
        assert issubclass(cls, BaselineAgent) and cls.name == name
    # a size the agent cannot take leaves no episode started
    agent = LainaAgent(config={"icp_downsample": 4})
    with pytest.raises(CnnSlamError, match="divisible"):
        agent.reset(K, (30, 40))
    with pytest.raises(CnnSlamError, match="before step"):
        agent.step(_obs(0.0, (30, 40)))
