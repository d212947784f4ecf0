"""CNN-SLAM as an agent of the simulated world (the contract of :mod:`sim_envs.agent`).

``"cnnslam.agent:CnnSlamAgent"`` is the paper's system with the trained network; it sees only observations.
``"cnnslam.agent:GroundTruthAidedAgent"`` declares ``uses_ground_truth = True`` and so also receives the env's
``info``: it exists for development and for the baselines that need ground truth, and uses it ONLY for (a) the
development depth predictor that degrades ground truth
(:class:`cnnslam.depth.depth_prediction.DegradedGroundTruthPredictor`)
on key-frame images, and (b) LSD-BS's ground-truth depth of the first key-frame (``preset="lsd_bs"``). Poses are
never taken from ground truth.

Keyword arguments (both classes; all optional)::

    CnnSlamAgent(preset="cnn_slam" | "raw" | "adjusted" | "refined" | "lsd" | "lsd_constant" | "lsd_bs",
                 config={"section.field": value, ...},  # overrides on top of the preset
                 predictor="network" | "degraded_ground_truth" | "package.module:Class" | "path/net.onnx" (or a
                           TorchScript file; cnnslam.depth.model_file) | <an object with predict_raw / train_focal>,
                 predictor_options={...},               # keywords of the predictor (weights=..., seed=...)
                 threads=True | False,                  # the paper's two threads, or deterministic single-thread
                 observers=[...])                       # cnnslam.system.SlamObserver-like (Python callers only)

The agent reports T_world_cam of every frame as it goes (the world frame is the first camera); ``finish()`` returns
the key-frames with their refined depth, pose-graph-optimised pose, depth variance and the CNN's class probabilities,
and the global model its key-frame thread fused (``AgentOutput.model``), and hands back the final trajectory (every
frame re-expressed through its key-frame's optimised pose, what :meth:`CnnSlamAgent.save_trajectory` writes) as
``AgentOutput.trajectory``, which the judge scores in place of the per-step answers (``system.output_trajectory =
"online"`` scores the per-step answers instead).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from cnnslam.config import ABLATIONS, BASELINES, CnnSlamConfig, ablation_config, baseline_config
from cnnslam.depth.depth_prediction import GroundTruthHint
from cnnslam.errors import CnnSlamError
from cnnslam.predictors import check_predictor_spec, make_predictor
from cnnslam.system import CnnSlam, SlamResult
from slamcommon.agent_keys import T_WORLD_CAM, TRACKED

PRESETS: tuple[str, ...] = tuple(dict.fromkeys(BASELINES + ABLATIONS))


def build_config(preset: str = "cnn_slam", config: CnnSlamConfig | dict[str, Any] | None = None,
                 threads: bool | None = None) -> CnnSlamConfig:
    """The configuration of a preset (an ablation of Fig. 3 or a Table-1 baseline) with overrides applied."""
    if isinstance(config, CnnSlamConfig):
        cfg = config
    else:
        if preset in ABLATIONS:
            cfg = ablation_config(preset)  # type: ignore[arg-type]
        elif preset in BASELINES:
            cfg = baseline_config(preset)  # type: ignore[arg-type]
        else:
            raise CnnSlamError(f"unknown preset {preset!r}; valid presets: {', '.join(PRESETS)}")
        cfg = cfg.with_overrides(config or {})
    if threads is not None:
        cfg = cfg.with_overrides({"system.threads": bool(threads)})
    return cfg


class CnnSlamAgent:
    """CNN-SLAM (Tateno et al. 2017) as a ``sim_envs`` agent; see the module docstring for the arguments."""

    uses_ground_truth = False
    default_predictor = "network"

    def __init__(
        self,
        preset: str = "cnn_slam",
        config: CnnSlamConfig | dict[str, Any] | None = None,
        predictor: str | Any | None = None,
        predictor_options: dict[str, Any] | None = None,
        threads: bool | None = None,
        observers: tuple[Any, ...] | list[Any] = (),
    ) -> None:
        self.config = build_config(preset, config, threads)
        self.observers = tuple(observers)  # cnnslam.system.SlamObserver-like: told of frames, fused key-frames, the end
        self.preset = preset
        if self.config.depth.source == "ground_truth_first" and not self.uses_ground_truth:
            raise CnnSlamError(
                "depth.source = 'ground_truth_first' (LSD-BS) needs ground truth: use "
                "cnnslam.agent:GroundTruthAidedAgent"
            )
        self._predictor_spec = self.default_predictor if predictor is None else predictor
        self._predictor_options = dict(predictor_options or {})
        if self.config.depth.uses_cnn:  # a bad predictor name, model file or training focal: now, before any frame
            check_predictor_spec(self._predictor_spec, self._predictor_options)
        if (isinstance(self._predictor_spec, str) and self._predictor_spec == "degraded_ground_truth"
                and not self.uses_ground_truth and self.config.depth.uses_cnn):
            raise CnnSlamError("the 'degraded_ground_truth' predictor needs ground truth: use "
                               "cnnslam.agent:GroundTruthAidedAgent")
        self._predictor: Any = None
        self._system: CnnSlam | None = None
        self._result: SlamResult | None = None
        self.name = f"cnn_slam[{preset}]" if preset != "cnn_slam" else "cnn_slam"

    @property
    def predictor(self) -> Any:
        """The depth predictor, built on first use (the network's weights are loaded lazily)."""
        if self._predictor is None and self.config.depth.uses_cnn:
            spec = self._predictor_spec
            self._predictor = make_predictor(spec, **self._predictor_options) if isinstance(spec, str) else spec
        return self._predictor

    def reset(self, intrinsics: np.ndarray, image_size: tuple[int, int]) -> None:
        """Start a new episode: ``intrinsics`` [fx, fy, cx, cy] pixels, ``image_size`` (H, W)."""
        if self._system is not None:
            self._system.close()
        self._result = None
        self._system = CnnSlam(self.config, np.asarray(intrinsics, dtype=np.float64), tuple(image_size),
                               self.predictor, self.observers)

    def step(self, observation: dict[str, np.ndarray]) -> dict[str, Any]:
        """Process one observation (``rgb``, ``timestamp``); answer ``{"T_world_cam": (4, 4), "tracked": 0|1}``."""
        return self._step(observation, None)

    def _step(self, observation: dict[str, np.ndarray], ground_truth: GroundTruthHint | None) -> dict[str, Any]:
        if self._system is None:
            raise CnnSlamError("call reset(intrinsics, image_size) before step()")
        stamp = float(np.asarray(observation["timestamp"]).reshape(-1)[0])
        out = self._system.process(observation["rgb"], stamp, ground_truth)
        return {T_WORLD_CAM: out.T_world_cam, TRACKED: int(out.tracked)}

    def finish(self) -> Any:
        """End the episode: an ``AgentOutput`` with the refined key-frames, the global model (its surfels' positions,
        fused labels, normals and colours) and JSON-serialisable extras."""
        from sim_envs.agent import AgentOutput, FinalTrajectory, KeyframeDepth, MapModel

        if self._system is None:
            raise CnnSlamError("finish() before reset()")
        self._result = self._system.finish()
        res = self._result
        keyframes = [
            KeyframeDepth(timestamp=k.timestamp, depth=k.depth, T_world_cam=k.T_world_kf, uncertainty=k.variance,
                          labels=k.label_probs if k.label_probs is not None else k.labels)
            for k in res.keyframes
        ]
        extras = dict(res.stats)
        extras["preset"] = self.preset
        extras["predictor"] = (self._predictor_spec if isinstance(self._predictor_spec, str)
                               else type(self._predictor_spec).__name__)
        extras["config"] = self.config.to_dict()
        model = None
        if res.model is not None:  # the global model fused live by the key-frame thread (Sec. 3.5)
            cloud = res.model.snapshot()
            model = MapModel(points=cloud.positions, labels=cloud.labels, normals=cloud.normals,
                             colours=cloud.colours)
        trajectory = None
        if self.config.system.output_trajectory == "final":  # what save_trajectory() writes; else the per-step poses
            trajectory = FinalTrajectory(res.timestamps, res.T_world_cam, res.tracked)
        return AgentOutput(keyframes=keyframes, extras=extras, model=model, trajectory=trajectory)

    @property
    def result(self) -> SlamResult | None:
        """The system's full result after :meth:`finish` (trajectories, key-frames with CNN depth, pose graph)."""
        return self._result

    def save_trajectory(self, path: str | Path, online: bool = False) -> Path:
        """Write the trajectory as a TUM file (``timestamp tx ty tz qx qy qz qw``) after :meth:`finish`.

        online=False (default): the final trajectory, every frame through its key-frame's optimised pose;
        online=True: the poses answered frame by frame.
        """
        from sim_envs.folders.formats import write_tum_trajectory

        if self._result is None:
            raise CnnSlamError("save_trajectory() needs finish() first")
        poses = self._result.T_world_cam_online if online else self._result.T_world_cam
        return write_tum_trajectory(path, self._result.timestamps, poses,
                                    header=f"cnnslam {self.name} ({'online' if online else 'final'} poses)")


class GroundTruthAidedAgent(CnnSlamAgent):
    """CNN-SLAM receiving ground truth, for development and baselines only (``uses_ground_truth = True``).

    The default predictor is the development one that degrades ground-truth depth; ``preset="lsd_bs"`` takes the
    first key-frame's depth from ground truth. Ground truth reaches nothing else (see the module docstring).
    """

    uses_ground_truth = True
    default_predictor = "degraded_ground_truth"

    def step(self, observation: dict[str, np.ndarray], info: dict[str, Any] | None = None) -> dict[str, Any]:
        """Like :meth:`CnnSlamAgent.step`; ``info["gt_depth"]`` (and ``gt_labels``) are used as described above."""
        hint = GroundTruthHint.from_info(info)
        return self._step(observation, hint)
