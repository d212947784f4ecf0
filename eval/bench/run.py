"""One benchmark run = (suite, sequence, method, seed, frames) -> a folder of artifacts (a suite's many runs:
:mod:`eval.bench.runner`; where the folders go: :mod:`eval.bench.run_store`).

A run (:func:`execute_run`, in a worker process) makes the sequence's environment, runs the method's agent over the
first ``frames`` frames with :func:`sim_envs.driver.run_episode` (or reads an external system's output), scores it
with :func:`eval.metrics.results.evaluate_episode`, and returns its artifacts as bytes; the parent process writes them
(:func:`eval.bench.run_store.store_result`), so the executor may be a process pool or a Ray cluster without a shared
file system.

Run folder ``OUT/<suite>/<sequence>/<method>/seed<seed>-frames<N>/`` (:data:`RUN_FILES`):

- ``metrics.json``: the run record (:mod:`eval.metrics.results`) with the method's metric groups only, and ``metadata``
  (suite, seed, frames, entry point and keyword arguments, environment id, sequence definition, git revision,
  fingerprint). Deterministic: the same run gives the same bytes (wall-clock figures are kept out of it);
- ``timing.json``: what the run used (:data:`eval.metrics.results.RESOURCE_FIGURES`: wall time, frames per second
  end to end and of the agent's step, peak resident memory of the run's process; an external system's wall time and
  frames per second are its own, from its ``run.toml``, or absent without one, and the judge's seconds
  ``scoring_wall_s``), its process's CPU time
  (``cpu_s``), per-frame step times, ``stages`` (where the run's wall seconds went, :data:`STAGES`; read by
  :mod:`eval.bench.profile`), ``frame_reads`` / ``frame_renders`` (frames read from the frame cache / rendered),
  ``unit_cpu_s`` / ``frames_per_unit`` (the machine unit timed around the run in the thread's CPU seconds,
  :mod:`slamcommon.machine_unit`, and the run's frames per unit of CPU time: the suite speed gate's figure,
  :mod:`eval.bench.suite_speed`), and ``environment``, the machine and package versions it ran on
  (:mod:`eval.bench.environment`; never compared by the gate; :func:`eval.metrics.results.load_run` reads them
  into the record's ``resources``);
- ``agent_extras.json``: the agent's own diagnostics (``AgentOutput.extras``);
- ``trajectory.tum`` / ``groundtruth.tum``: estimated (the agent's own frame and scale) and ground-truth poses;
- ``trajectory_aligned_se3.tum`` and, for a monocular method, ``trajectory_aligned_sim3.tum``: the estimate aligned
  onto the ground truth (``evo_ape -a`` / ``-as``; :mod:`eval.metrics.aligned`), ready for ``evo_traj`` and
  ``evo_ape`` without an alignment flag;
- ``keyframes.npz``: ``timestamps`` (K,), ``T_world_cam`` (K, 4, 4), ``depth`` (K, H, W) float32 metres (resized to
  the ground truth's size where it differed, as scored), ``uncertainty`` (K, H, W) when every key-frame has one;
- ``trajectory.png`` (top view, axes over time, ATE over time) and ``depth.png`` (up to 3 key-frames' error maps),
  unless plots are off.

A failed run's folder holds only ``failed.json`` (error, traceback, wall time). The run's fingerprint
(:meth:`RunSpec.fingerprint`: method, sequence definition, seed, frames, alignment, renderer, the SHA-256 of the
method's ``inputs`` files such as network weights, the agent's import closure, the world's and the judge's code)
decides whether a finished run is reused (:mod:`eval.bench.runner`); writes are atomic (:mod:`eval.bench.run_store`).
"""

from __future__ import annotations

import json
import math
import tempfile
import time
import traceback
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Literal

import numpy as np

from eval.bench.environment import machine_description
from eval.bench.methods import RUN_SIDE_FILE, TIMING_METRICS, Method, resolve_input
from eval.bench.sequence_ref import SequenceRef
from eval.errors import RunnerError
from eval.metrics.aligned import ALIGNED_FILES, aligned_alignments, aligned_files
from eval.metrics.association import associate
from eval.metrics.catalogue import FPS_END_TO_END, FRAMES, METHOD_WALL_S, PEAK_RSS_MIB, TRACKED_SHARE, WALL_S
from eval.metrics.map_metrics import map_metrics
from eval.metrics.results import TIMING_FILE, evaluate_episode, json_ready
from eval.metrics.runs import (  # a run folder's record files and its trajectory's scoring: the judge's, so that
    DONE_FILE,  # noqa: F401  the reports read them back without importing the benchmark (names kept here)
    FAILED_FILE,  # noqa: F401
    run_trajectory_metrics,
)
from eval.metrics.trajectory import PoseTrajectory, rotation_share
from eval.metrics.trajectory_metrics import TrajectoryMetrics
from sim_envs.sensor.camera_effects import DEFAULT_CAMERA_EFFECTS
from slamcommon.machine_unit import UNIT_VERSION, machine_unit_seconds, unit_summary
from slamcommon.resources import peak_resident_mib

RUN_FILES: tuple[str, ...] = (
    "metrics.json",
    "timing.json",
    "agent_extras.json",
    "trajectory.tum",
    "groundtruth.tum",
    *ALIGNED_FILES.values(),
    "keyframes.npz",
    "trajectory.png",
    "depth.png",
)
FRAME_CACHE_DIR = ".frames"  # under a suite's output root: simulated frames rendered once, read by its other runs
RunStatus = Literal["done", "cached", "failed", "not_run"]
DEPTH_PNG_SCALE = 5000.0  # TUM depth PNGs: 5000 = 1 m (external systems' depth maps)
DEPTH_PLOT_KEYFRAMES = 3  # key-frames shown in a run's depth.png (first, middle, last)
UNIT_REPEATS = 30  # machine units timed before and after a run (0.4 ms each on a 2-core EPYC: ~25 ms a run)
# where a run's wall seconds go (timing.json "stages"): building the agent and the environment; reading (or
# rendering) frames; the agent's steps; its finish(); the rest of the episode loop (the env's observations, the
# driver's checks); scoring the trajectory; scoring key-frame depth and labels; scoring the global model; writing
# the run's files; drawing its plots; and whatever is left (other)
STAGES: tuple[str, ...] = ("setup", "frames", "agent", "finish", "env_driver", "trajectory_metrics",
                           "keyframe_metrics", "map_metrics", "files", "plots", "other")


@dataclass(frozen=True)
class RunSpec:
    """Everything one run needs; picklable (sent to workers). ``frames``: the first N frames (None: all)."""

    suite: str
    sequence: SequenceRef
    method: Method
    seed: int = 0
    frames: int | None = None
    alignment: str = "se3"
    renderer: str = "mujoco"
    plots: bool = True
    git_revision: str | None = None
    frame_cache: str | None = None  # where simulated frames are kept once rendered (same bytes; not fingerprinted)
    # the fingerprint as the planner computed it in the parent process (not a part of it): a worker then records it
    # without parsing the agent's import closure again (a fresh worker per run: about 0.5 s of CPU a run)
    known_fingerprint: str | None = None

    @property
    def relpath(self) -> Path:
        """The run's folder relative to the output root."""
        frames = "all" if self.frames is None else str(self.frames)
        return Path(self.suite) / self.sequence.name / self.method.slug / f"seed{self.seed}-frames{frames}"

    @property
    def key(self) -> str:
        """A readable unique name of the run (its relative folder)."""
        return self.relpath.as_posix()

    def fingerprint(self) -> str:
        """Hash of what determines the run's result (:func:`eval.bench.fingerprint.run_parts`): the files of the
        agent's import closure, the world's code its frames come through, the judge's metric code, the contents of
        the method's input files such as network weights, and its configuration (method, sequence definition,
        seed, frames, alignment, renderer); not the git revision, so a commit that leaves what a run executes alone
        does not invalidate its finished runs, but new weights or an edited file the agent imports do."""
        if self.known_fingerprint is not None:
            return self.known_fingerprint
        from eval.bench.fingerprint import run_parts

        return run_parts(self).fingerprint


@dataclass(frozen=True)
class RunResult:
    """What a worker hands back: ``status`` "done" with ``files`` (name -> bytes), or "failed" with ``error``."""

    spec: RunSpec
    status: RunStatus
    files: dict[str, bytes] = field(default_factory=dict)
    error: str | None = None
    traceback: str | None = None
    seconds: float = 0.0  # wall-clock seconds the run took, done or failed


# --------------------------------------------------------------------------------------- frames ahead of runs
@dataclass(frozen=True)
class FramesJob:
    """Render the first ``frames`` frames (None: all) of a simulated ``sequence`` into the frame cache under
    ``cache`` before the suite's runs read them (:func:`render_frames`); picklable, like a :class:`RunSpec`."""

    sequence: SequenceRef
    frames: int | None
    renderer: str
    cache: str

    @property
    def key(self) -> str:
        """A readable name of the job."""
        return f"frames of {self.sequence.name} ({'all' if self.frames is None else self.frames})"


def render_frames(job: FramesJob) -> int:
    """Render (and store) every frame of ``job`` the cache lacks, and the sequence's timestamps and poses; returns
    how many frames were rendered (0: all were there). The frames are those any run would render (same bytes)."""
    source = job.sequence.make_source(job.renderer, job.cache)
    rendered = 0
    try:
        with source.filling():  # the runs of this sequence that start meanwhile wait for it, not render beside it
            n = len(source) if job.frames is None else min(len(source), int(job.frames))
            source.timestamps  # noqa: B018 - kept in the cache beside the frames
            for i in range(n):
                if not source.has(i):
                    source.frame(i)
                    rendered += 1
    finally:
        source.close()
    return rendered


# ------------------------------------------------------------------------------------------------- one run
@dataclass(frozen=True)
class ExternalEpisode:
    """An external system's output in the shape :func:`eval.metrics.results.evaluate_episode` reads (the fields of
    ``sim_envs.driver.EpisodeResult`` it uses); poses already associated with the ground truth, pair k = k."""

    sequence: str
    agent: str
    timestamps: np.ndarray
    T_world_cam_est: np.ndarray
    T_world_cam_gt: np.ndarray
    tracked: np.ndarray
    keyframes: list[Any]
    keyframe_gt: list[Any]
    step_seconds: np.ndarray
    uses_ground_truth: bool = False
    extras: dict[str, Any] = field(default_factory=dict)


def execute_run(spec: RunSpec, progress: bool = False) -> RunResult:
    """Run, score and package one run; never raises for a failing run (it comes back ``failed`` with the error)."""
    _wait_for_rendering(spec)  # a sequence still rendering (another task of the suite) is not the run's time
    units = [machine_unit_seconds(time.thread_time) for _ in range(UNIT_REPEATS)]  # before the run's clocks start
    start = time.perf_counter()
    try:
        files = _run_and_package(spec, progress, start, units, time.process_time())
    except Exception as exc:  # noqa: BLE001 - a failing run is recorded with its error; the others go on
        return RunResult(
            spec,
            "failed",
            error=f"{type(exc).__name__}: {exc}",
            traceback=traceback.format_exc(),
            seconds=time.perf_counter() - start,
        )
    return RunResult(spec, "done", files=files, seconds=time.perf_counter() - start)


def _wait_for_rendering(spec: RunSpec) -> None:
    """Wait until no process is filling the frame cache of ``spec``'s sequence (``CachedFrames.filling``, a suite's
    rendering job); nothing to wait for without a frame cache or for a folder sequence. Never raises: a sequence
    that cannot even be made fails in the run, with its error."""
    if spec.frame_cache is None or spec.sequence.folder is not None:
        return
    try:
        source = replace(spec.sequence, start=0).make_source(spec.renderer, spec.frame_cache)
        try:
            wait = getattr(source, "wait_for_writer", None)
            if wait is not None:
                wait()
        finally:
            source.close()
    except Exception:  # noqa: BLE001, S110 - the run reports it
        pass


def _run_and_package(spec: RunSpec, progress: bool, start: float, units: list[float] | None = None,
                     cpu_start: float | None = None) -> dict[str, bytes]:
    method, ref = spec.method, spec.sequence
    scene = None
    stages: dict[str, float] = {}
    reads: dict[str, int] = {}
    given = None
    if method.kind == "external":
        episode, n_frames, source_info = _external_episode(spec)
    else:
        episode, source_info, scene, given = _agent_episode(spec, progress, stages, reads)
        n_frames = int(episode.timestamps.shape[0])
    metadata = {
        "suite": spec.suite,
        "seed": spec.seed,
        "frames_requested": spec.frames,
        "entry_point": method.entry_point or f"external:{method.folder}",
        "agent_kwargs": json.dumps(method.agent_kwargs(spec.seed), sort_keys=True),
        "env_id": ref.env_id,
        "renderer": spec.renderer,
        "axis": ref.axis,
        "axis_value": ref.axis_value,
        "rotation_share": rotation_share(np.asarray(episode.T_world_cam_gt)),
        "git_revision": spec.git_revision,
        "fingerprint": spec.fingerprint(),
        "sequence_definition": ref.describe(),
        "method_definition": method.describe(),
    }
    if given is not None:
        metadata["method_input"] = given  # what the agent was given: image size, undistortion, camera, input files
    if source_info is not None:
        metadata["source"] = source_info  # a folder's layout, original size, camera, depth scale, conversions
    record = evaluate_episode(episode, alignment=spec.alignment, method=method.name, metadata=metadata,
                              seconds=stages)
    record = record.replace(sequence=ref.name)
    metrics = dict(record.metrics)
    has_depth = source_info is None or source_info.get("has_depth", True)
    if not has_depth:  # an RGB-only folder: nothing to score key-frame depth against
        metrics = {k: v for k, v in metrics.items() if not k.startswith("depth_")}
        record = record.with_warning(f"{ref.name} has no ground-truth depth (RGB-only folder): depth metric skipped")
    model = getattr(episode, "model", None)
    if model is not None and scene is not None and len(model):  # the global model against the scene's surfaces
        t_map = time.perf_counter()
        metrics.update(map_metrics(model, episode.T_world_cam_gt, episode.T_world_cam_est, episode.keyframe_gt,
                                   episode.intrinsics.as_array(), scene, str(spec.alignment)))
        metrics["map_scoring_s"] = stages["map_metrics"] = time.perf_counter() - t_map
    if method.kind == "external":
        metrics["frames"] = float(n_frames)
        metrics[TRACKED_SHARE.key] = float(len(episode.timestamps)) / n_frames
        # the poses were matched by timestamp before scoring (TUM rule): record that, not the index pairing after it
        record = record.replace(association=episode.extras["association"],
                                uses_ground_truth=bool(method.uses_ground_truth),
                                ground_truth_used=tuple(method.uses_ground_truth))  # as its method.toml declares
    timing = {k: metrics[k] for k in TIMING_METRICS if k in metrics}
    record = record.replace(sensor=method.sensor, metrics=method.select_metrics(metrics))
    timing["finish_seconds"] = episode.extras.get("finish_seconds")
    if episode.extras.get("own_seconds") is not None:
        timing[METHOD_WALL_S.key] = episode.extras["own_seconds"]  # the system's own run time (its run.toml)

    with tempfile.TemporaryDirectory(prefix="cnnslam-run-") as tmp:
        folder = Path(tmp)
        t_files = time.perf_counter()
        write_json(folder / "metrics.json", record.to_json())
        write_json(folder / "agent_extras.json", episode.extras)
        _write_tum(folder / "trajectory.tum", episode.timestamps, episode.T_world_cam_est, f"estimate: {method.name}")
        _write_tum(folder / "groundtruth.tum", episode.timestamps, episode.T_world_cam_gt, f"ground truth: {ref.name}")
        scored = run_trajectory_metrics(episode.timestamps, episode.T_world_cam_gt, episode.T_world_cam_est,
                                        spec.alignment)  # fmt: skip
        for name, text in aligned_files(scored, aligned_alignments(method.sensor), run_title(spec)).items():
            (folder / name).write_text(text)
        depth_est, depth_gt = _write_keyframes(folder / "keyframes.npz", episode)
        t_plots = time.perf_counter()
        stages["files"] = t_plots - t_files
        if spec.plots:
            _write_plots(folder, spec, episode, scored, depth_est if has_depth else [], depth_gt)
            stages["plots"] = time.perf_counter() - t_plots
        timing[WALL_S.key] = time.perf_counter() - start
        timing.update(resource_figures(n_frames, timing[WALL_S.key]))
        if cpu_start is not None:  # CPU seconds of the run's process, all its threads: what a loaded machine's wall
            timing["cpu_s"] = time.process_time() - cpu_start  # time hides
        stages["other"] = max(0.0, timing[WALL_S.key] - sum(stages.values()))
        if method.kind == "external":
            _external_speed(timing, n_frames)
        timing["stages"] = {k: stages[k] for k in STAGES if k in stages}
        timing.update(reads)
        # the run's speed in machine units (slamcommon.machine_unit, timed here just before and just after it, in this
        # thread's CPU seconds; the run in its process's, all threads), CPU time, which other processes on the cores
        # do not inflate as they do wall time: what the suite speed gate compares (eval.bench.suite_speed)
        units = [*(units or []), *(machine_unit_seconds(time.thread_time) for _ in range(UNIT_REPEATS))]
        timing["unit_version"] = UNIT_VERSION
        timing["unit_cpu_s"] = unit_summary(units)
        cpu = timing.get("cpu_s") or 0.0
        timing["frames_per_unit"] = n_frames * timing["unit_cpu_s"] / cpu if cpu > 0 else 0.0
        timing["environment"] = machine_description()  # which CPU and versions made these bytes
        write_json(folder / TIMING_FILE, timing)
        return {p.name: p.read_bytes() for p in sorted(folder.iterdir()) if p.is_file()}


def _external_speed(timing: dict[str, Any], frames: int) -> None:
    """An external system's speed is its own: the run's wall time and end-to-end frames a second (:data:`WALL_S`,
    :data:`FPS_END_TO_END`: what the speed tables show) become the seconds its ``run.toml`` declares
    (:data:`METHOD_WALL_S`) and frames / those, or are left out when it declares none (the judge only read and scored
    its output); the judge's own seconds stay as ``scoring_wall_s``."""
    timing["scoring_wall_s"] = timing.pop(WALL_S.key)
    timing.pop(FPS_END_TO_END.key, None)
    own = timing.get(METHOD_WALL_S.key)
    if own is not None:
        timing[WALL_S.key] = float(own)
        timing[FPS_END_TO_END.key] = frames / own if own > 0 else math.nan


def resource_figures(frames: int, seconds: float) -> dict[str, float]:
    """What this process used for a run of ``frames`` frames that took ``seconds``, under the catalogue's keys:
    :data:`FRAMES`, :data:`FPS_END_TO_END` and the peak resident memory so far (MiB) of this process,
    :data:`PEAK_RSS_MIB` (a fresh worker per run by default; with reused workers or the serial executor, that
    process's peak so far)."""
    return {
        FRAMES.key: float(frames),
        FPS_END_TO_END.key: frames / seconds if seconds > 0 else math.nan,
        PEAK_RSS_MIB.key: peak_resident_mib(),
    }


def run_title(spec: RunSpec) -> str:
    """How a run's figures and files name it: method, sequence and seed."""
    return f"{spec.method.name} on {spec.sequence.name} (seed {spec.seed})"


def _agent_episode(spec: RunSpec, progress: bool, stages: dict[str, float] | None = None,
                   reads: dict[str, int] | None = None) -> tuple[Any, dict[str, Any] | None, Any, dict[str, Any]]:
    """The agent's episode, the frame source's own description (:func:`_source_info`), its scene (simulated
    sequences whose agent handed back a model; None for folders and without a model) and what the agent was given
    (:func:`given_input`; the sequence as the method's ``input`` asks, :meth:`Method.given_sequence`). Raises
    :class:`RunnerError` before the episode when a method whose ``input`` is ``native`` would be given distorted
    images its agent does not take the distortion of. ``stages``: the wall seconds
    of the episode's stages are added to it (setup, frames, agent, finish, env_driver; see :data:`STAGES`);
    ``reads``: the frames read from the frame cache and rendered (``frame_reads``, ``frame_renders``; a source
    without a cache counts none)."""
    from sim_envs.agent import load_agent
    from sim_envs.driver import run_episode

    stages = {} if stages is None else stages
    t0 = time.perf_counter()
    agent = load_agent(spec.method.entry_point or "", **spec.method.agent_kwargs(spec.seed))
    ref = spec.method.given_sequence(spec.sequence)
    env = ref.make_env(max_frames=spec.frames, renderer=spec.renderer, frame_cache=spec.frame_cache)
    try:
        source = env.unwrapped.source
        given = given_input(env, agent, spec.method)
        if spec.method.input == "native" and given["undistortion"] == "none" and env.unwrapped.distortion.any():
            raise RunnerError(f"method {spec.method.name!r} has input = 'native', but its agent "
                              f"{spec.method.entry_point} does not take the lens distortion (takes_distortion = True, "
                              f"sim_envs/agent.py) of {ref.name}'s distorted images; give it input = 'harness'")
        t1 = time.perf_counter()
        stages["setup"] = t1 - t0
        episode = run_episode(env, agent, progress=progress)
        t2 = time.perf_counter()
        # the room, for the map metrics only: generating it costs a second or more, so not for agents without a map
        scene = getattr(source, "scene", None) if getattr(episode, "model", None) is not None else None
        frames_s = float(getattr(source, "read_seconds", 0.0)) + float(getattr(source, "render_seconds", 0.0))
        agent_s = float(np.sum(episode.step_seconds))
        finish_s = float(episode.extras.get("finish_seconds") or 0.0)
        stages.update(frames=frames_s, agent=agent_s, finish=finish_s,
                      env_driver=max(0.0, (t2 - t1) - frames_s - agent_s - finish_s))
        if reads is not None:
            reads.update(frame_reads=int(getattr(source, "reads", 0)), frame_renders=int(getattr(source, "renders", 0)))
        return episode, _source_info(source), scene, given
    finally:
        env.close()


def given_input(env: Any, agent: Any, method: Method) -> dict[str, Any]:
    """What ``env`` gives ``agent`` (run metadata ``method_input``): the method's ``input`` setting, the delivered
    ``image_size`` (width, height pixels), ``intrinsics`` (fx, fy, cx, cy pixels), the lens ``distortion`` handed to
    the agent (k1 k2 p1 p2 k3, OpenCV model; zeros for pinhole images and for agents that take none), who undistorts
    the images (``undistortion``: ``harness`` when the folder undistorts a distorted lens, ``method`` when the agent
    is given the distortion of images left distorted, ``none`` otherwise: a pinhole camera, or distorted images an
    agent takes as pinhole ones) and the method's input files (``files``: name -> file name and bytes, such as a
    vocabulary or network weights)."""
    from sim_envs.agent import takes_distortion
    from sim_envs.camera import DISTORTION_NAMES
    from sim_envs.env import delivered_distortion

    base = env.unwrapped
    source = base.source
    height, width = base.observation_space["rgb"].shape[:2]
    K = source.intrinsics
    lens = delivered_distortion(source)
    lens_distorted = bool(getattr(getattr(source, "camera", None), "distorted", False))
    takes = takes_distortion(agent)
    if lens_distorted and not lens.any():
        undistortion = "harness"
    elif lens.any() and takes:
        undistortion = "method"
    else:
        undistortion = "none"
    given = lens if takes else np.zeros_like(lens)
    files = {}
    for name in method.inputs:
        path = resolve_input(name, method.name)
        files[name] = {"file": path.name, "bytes": path.stat().st_size}
    return {
        "input": method.input,
        "image_size": {"width": int(width), "height": int(height)},
        "undistortion": undistortion,
        "intrinsics": {"fx": float(K.fx), "fy": float(K.fy), "cx": float(K.cx), "cy": float(K.cy)},
        "distortion": {n: float(v) for n, v in zip(DISTORTION_NAMES, given, strict=True)},
        "files": files,
    }


def _source_info(source: Any) -> dict[str, Any] | None:
    """What a frame source says about itself (``describe()``: a real folder's layout, sizes, camera, depth scale,
    conversions), for the run record; None for sources that say nothing (the simulated ones)."""
    describe = getattr(source, "describe", None)
    return describe() if callable(describe) else None


def _external_episode(spec: RunSpec) -> tuple[ExternalEpisode, int, dict[str, Any] | None]:
    """The external system's trajectory (and depth maps) for the sequence, associated with the ground truth of the
    first ``frames`` frames (TUM greedy association, 0.02 s); returns the episode, the number of frames and the
    source's description."""
    from sim_envs.agent import KeyframeDepth
    from sim_envs.driver import match_timestamp

    ref, method = spec.sequence, spec.method
    folder = Path(method.folder or "")
    names = [ref.name]
    if ref.base is not None and dict(ref.overrides) == {"camera_effects": DEFAULT_CAMERA_EFFECTS}:
        names.append(ref.base)  # `cnnslam export office0 data/office0` exports office0 through the default camera
    candidates = [p for name in names for p in (folder / name / "trajectory.txt", folder / f"{name}.txt")]
    path = next((p for p in candidates if p.is_file()), None)
    if path is None:
        raise RunnerError(
            f"external method {method.name!r}: no trajectory for {ref.name!r}; looked for "
            f"{', '.join(str(p) for p in candidates)}"
        )
    sequence_dir = path.parent if path.name == "trajectory.txt" else folder / ref.name  # its depth/, run.toml
    source = ref.make_source(spec.renderer, spec.frame_cache)
    source_info = _source_info(source)
    try:
        n = len(source) if spec.frames is None else min(len(source), int(spec.frames))
        gt = PoseTrajectory(np.asarray(source.timestamps)[:n], np.asarray(source.poses)[:n])
        dropped: list[str] = []  # repeated timestamps: the last pose kept, as the TUM tools and evo do
        est = PoseTrajectory.from_tum_file(path, duplicate_timestamps="last", on_duplicates=dropped.append)
        assoc = associate(gt, est, "tum")
        T_est = est.T_world_cam[assoc.est_indices]
        stamps = gt.timestamps[assoc.gt_indices]
        keyframes, keyframe_gt = [], []
        depth_dir = sequence_dir / "depth"
        files = sorted(depth_dir.glob("*.png")) + sorted(depth_dir.glob("*.npy")) if depth_dir.is_dir() else []
        for file in files:
            t = float(file.stem)
            i = match_timestamp(gt.timestamps, t)
            if i is None:
                continue
            k = int(np.argmin(np.abs(stamps - t))) if stamps.size else -1
            pose = T_est[k] if k >= 0 else np.eye(4)
            keyframes.append(KeyframeDepth(float(gt.timestamps[i]), _read_depth(file), pose))
            keyframe_gt.append(source.frame(i))
    finally:
        source.close()
    episode = ExternalEpisode(
        sequence=ref.name,
        agent=f"external:{folder}",
        timestamps=stamps,
        T_world_cam_est=T_est,
        T_world_cam_gt=gt.T_world_cam[assoc.gt_indices],
        tracked=np.ones(len(assoc), dtype=bool),
        keyframes=keyframes,
        keyframe_gt=keyframe_gt,
        step_seconds=np.zeros(0),
        extras={"trajectory_file": str(path), "depth_files": len(files), "association": assoc.describe(),
                "duplicate_timestamps": dropped,
                "own_seconds": _declared_seconds(sequence_dir / RUN_SIDE_FILE)},
    )
    return episode, n, source_info


def _declared_seconds(path: Path) -> float | None:
    """The run time in seconds an external system's ``<sequence>/run.toml`` declares (its own, under the key of
    :data:`WALL_S`), None without the file."""
    import tomllib

    if not path.is_file():
        return None
    try:
        value = tomllib.loads(path.read_text(encoding="utf-8")).get(WALL_S.key)
    except (OSError, tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise RunnerError(f"{path}: not valid TOML: {exc}") from exc
    if not isinstance(value, int | float) or isinstance(value, bool) or not 0 <= value < math.inf:
        raise RunnerError(f"{path}: {WALL_S.key} must be a finite number of seconds >= 0, got {value!r}")
    return float(value)


def _read_depth(path: Path) -> np.ndarray:
    """An external depth map: 16-bit PNG (5000 = 1 m) or ``.npy`` float metres; (H, W) float32, 0 = none."""
    import cv2

    if path.suffix == ".npy":
        depth = np.load(path).astype(np.float32)
    else:
        raw = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
        if raw is None:
            raise RunnerError(f"cannot read the depth map {path}")
        depth = raw.astype(np.float32) / DEPTH_PNG_SCALE
    if depth.ndim != 2:
        raise RunnerError(f"{path}: a depth map must be (H, W), got {depth.shape}")
    return np.nan_to_num(depth, nan=0.0, posinf=0.0, neginf=0.0)


def write_json(path: Path, data: Any) -> None:
    path.write_text(json.dumps(json_ready(data), indent=2, allow_nan=False, default=str) + "\n")


def _write_tum(path: Path, timestamps: np.ndarray, T: np.ndarray, header: str) -> None:
    from slamcommon.formats import write_tum_trajectory

    write_tum_trajectory(path, np.asarray(timestamps), np.asarray(T), header=header)


def _write_keyframes(path: Path, episode: Any) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Key-frame arrays as scored (see the module docstring); returns the (estimate, ground truth) depth lists.
    Ground-truth depth is not stored: the sequence renders it again (``SequenceRef.make_source().frame(i)``)."""
    import cv2

    depth_est, depth_gt, stamps, poses, unc = [], [], [], [], []
    for kf, frame in zip(episode.keyframes, episode.keyframe_gt, strict=False):
        gt = np.asarray(frame.depth, dtype=np.float32)
        est = np.asarray(kf.depth, dtype=np.float32)
        if est.shape != gt.shape:
            est = cv2.resize(est, gt.shape[::-1], interpolation=cv2.INTER_NEAREST)
        depth_est.append(est)
        depth_gt.append(gt)
        stamps.append(float(kf.timestamp))
        poses.append(np.asarray(kf.T_world_cam, dtype=np.float64))
        u = getattr(kf, "uncertainty", None)
        unc.append(None if u is None or np.shape(u) != est.shape else np.asarray(u, dtype=np.float32))
    arrays: dict[str, np.ndarray] = {
        "timestamps": np.asarray(stamps, dtype=np.float64),
        "T_world_cam": np.asarray(poses, dtype=np.float64).reshape(-1, 4, 4),
    }
    if depth_est:
        arrays["depth"] = np.stack(depth_est)
        if all(u is not None for u in unc):
            arrays["uncertainty"] = np.stack(unc)  # type: ignore[arg-type]
    # stored uncompressed: deflate made float depth and uncertainty only 12 % smaller (CNN-SLAM on office0, 51
    # key-frames: 31.3 -> 27.5 MB) for 1.1 s a run, a twentieth of the run's wall time
    np.savez(path, **arrays)
    return depth_est, depth_gt


def _write_plots(folder: Path, spec: RunSpec, episode: Any, scored: TrajectoryMetrics, depth_est: list,
                 depth_gt: list) -> None:
    from eval.reports.plots import save_depth_error_figure, save_trajectory_figure
    from eval.reports.style import method_style

    title = run_title(spec)
    if "trajectory" in spec.method.metrics:
        save_trajectory_figure(folder / "trajectory.png", scored.gt.timestamps, scored.gt.positions,
                               scored.est_aligned.positions, scored.ate_errors, title,
                               style=method_style(spec.method.name))  # fmt: skip
    if depth_est:
        picks = sorted({0, len(depth_est) // 2, len(depth_est) - 1})[:DEPTH_PLOT_KEYFRAMES]
        stamps = [float(t) for t in (kf.timestamp for kf in episode.keyframes)]
        save_depth_error_figure(
            folder / "depth.png",
            [depth_est[k] for k in picks],
            [depth_gt[k] for k in picks],
            [f"{title}\nkey-frame t={stamps[k]:.2f} s" for k in picks],
        )
