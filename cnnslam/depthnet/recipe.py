"""The shipped network's whole recipe, from nothing: render the data, train, and hand back the run folder.

``cnnslam train recipe`` runs :func:`run_recipe` with :data:`SHIPPED` (one command retrains the shipped network; the
README says how long it takes on 2 CPU cores and on a GPU). Every step is resumable (finished shards are skipped, the
fit continues from its checkpoint), and every output is a function of the recipe alone: the same recipe and renderer
give the same data bytes (another OpenGL implementation, e.g. a GPU's against Mesa's llvmpipe, rasterises a few edge
pixels differently), and the batches are the same on any machine (the weights then differ in the last bits of the
arithmetic: a GPU's bf16 or another CPU's kernels).

What the recipe is made of, and why (ours; real frames are never used: they are test data):

- Data: rooms of the training styles only (never the test styles office / living), each drawn flat or lit (lamps,
  shadows, highlights: shading is a depth cue real images always have), standard or rich (clutter and texture at
  several scales), through a clean or a Kinect-like moving camera (``sim_envs.sensor.camera_effects``), at the NYU focal
  length times a log-uniform factor in [0.8, 1.25] (the network sees many focal lengths and learns eq. 5's premise,
  CAM-Convs' finding that a network trained on one camera does not transfer to another).
- Augmentation: the colour jitter of the first networks plus a camera pipeline on half the samples (vignetting,
  motion blur, shot noise, JPEG; :func:`cnnslam.depthnet.data.camera_pipeline`), full 160x120 images (a network
  trained on crops predicted 0.96 of the depth on full images).
- Loss: berHu on log depth (metric), plus the scale-invariant log loss (Eigen et al.) and the multi-scale gradient
  matching of MegaDepth / MiDaS, which weigh the depth's shape and its edges, plus cross-entropy for the labels.
- Model: the shipped architecture (ResNet-18 trunk of width 32, 3.8 M parameters): inference cost unchanged.

:data:`CLOSE_RANGE` ("shipped-v3") fine-tunes :data:`SHIPPED`'s weights (checked by their SHA-256) on new views of
training rooms, half of them 0.4-1.5 m from a surface (``GenerationConfig.close_range``: look-down floors and table
tops, desks with objects, close walls and cupboards: what hand-held cameras see at a desk), the other half drawn as
SHIPPED draws them: cheap enough for 2 CPU cores (``cnnslam train recipe --recipe shipped-v3``).

Resuming: ``run_recipe`` may be stopped at any moment (Ctrl-C, ``kill``, ``timeout``) and called again with the same
recipe and root: finished shards are kept, a half-written one is rendered again, the fit continues from its last
checkpoint (``checkpoint_every`` steps) with the same batches, and the stages' seconds add up over the calls
(``root/recipe.json``). A fine-tune's start is copied to ``root/start.pt`` on the first call (an export over the
shipped default in between changes nothing). A root holding another recipe's work is refused.
"""

from __future__ import annotations

import json
import os
import time
from collections.abc import Callable, Iterator
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

from cnnslam.depthnet.data import AugmentConfig, GenerationConfig, generate_dataset
from cnnslam.depthnet.train import TrainConfig, TrainResult, train
from cnnslam.depthnet.weights_io import DEFAULT_WEIGHTS
from cnnslam.errors import CnnSlamError

Progress = Callable[[Iterator[Any], int], Iterator[Any]]


@dataclass(frozen=True)
class Recipe:
    """Data, validation rooms and training of one network (see the module docstring)."""

    generation: GenerationConfig
    val_scenes: int
    fit: TrainConfig
    name: str = "recipe"
    # A fine-tune's start: "default" (the shipped weights, cnnslam/depthnet/weights/default.pt) or a weights file;
    # None: from scratch. init_sha256: the start's SHA-256, checked before any work (None: not checked).
    init_weights: str | None = None
    init_sha256: str | None = None

    def to_dict(self) -> dict[str, Any]:
        """JSON-serialisable form (the manifest records it)."""
        return {"name": self.name, "generation": asdict(self.generation), "val_scenes": self.val_scenes,
                "fit": self.fit.to_dict(), "init_weights": self.init_weights, "init_sha256": self.init_sha256}

    def start_weights(self) -> Path | None:
        """The fine-tune's start file (``init_weights`` resolved), or None for a run from scratch."""
        if self.init_weights is None:
            return None
        return DEFAULT_WEIGHTS if self.init_weights == "default" else Path(self.init_weights)


SHIPPED = Recipe(
    name="shipped-v2",
    generation=GenerationConfig(
        n_scenes=1400, views_per_scene=20, data_seed=10, focal_scale=(0.8, 1.25),
        camera_effects=("clean", "kinect"), lighting=("flat", "lit"), detail=("standard", "rich"),
    ),
    val_scenes=40,
    fit=TrainConfig(
        batch_size=64, steps=7_000, lr=1e-3, min_lr=1e-5, warmup_steps=500, semantic_weight=0.5,
        depth_space="log", silog_weight=0.5, gradient_weight=0.5, val_every=2_000, checkpoint_every=500,
        augment=replace(AugmentConfig(), crop=(120, 160), p_camera=0.5),
    ),
)


CLOSE_RANGE = Recipe(
    name="shipped-v3",
    generation=replace(SHIPPED.generation, n_scenes=160, data_seed=13, close_range=0.5),
    val_scenes=16,
    fit=replace(SHIPPED.fit, batch_size=16, steps=500, lr=1e-4, min_lr=1e-4, warmup_steps=0, seed=13,
                val_every=250, checkpoint_every=25),
    init_weights="default",
    init_sha256="e28c80a966e1077e4ff417f6b3f1d3c6ded950670cb3517c8c2b7554b6ebb4f0",  # SHIPPED's weights
)

RECIPES: dict[str, Recipe] = {r.name: r for r in (SHIPPED, CLOSE_RANGE)}  # cnnslam train recipe --recipe NAME


def get_recipe(name: str) -> Recipe:
    """The recipe called ``name`` (:data:`RECIPES`)."""
    if name not in RECIPES:
        raise CnnSlamError(f"unknown recipe {name!r}; known: {', '.join(RECIPES)}")
    return RECIPES[name]


@dataclass(frozen=True)
class RecipeResult:
    """What :func:`run_recipe` made: the data root, the fit's result and the wall time of each stage (s)."""

    data_root: Path
    fit: TrainResult
    seconds: dict[str, float] = field(default_factory=dict)


def run_recipe(
    recipe: Recipe,
    root: str | Path,
    device: str = "cpu",
    render_workers: int = 2,
    loader_workers: int = 1,
    threads: int = 2,
    progress: Progress | None = None,
    train_progress: bool = True,
    on_step: Callable[[int, float], None] | None = None,
) -> RecipeResult:
    """Render the recipe's data under ``root/data`` and train under ``root/run``; a second call after an
    interruption goes on where the first stopped (module docstring).

    device: "cpu" or "cuda"; render_workers: render processes; loader_workers: batch processes of the fit (1: one
    thread); threads: torch's intra-op threads; on_step(step, loss): called after every optimiser step. Returns the
    run's weights and manifest (``root/run``); ``seconds`` are the stages' totals over every call.
    """
    if render_workers < 0 or loader_workers < 1 or threads < 1:
        raise CnnSlamError(f"need render_workers >= 0, loader_workers >= 1 and threads >= 1, got {render_workers}, "
                           f"{loader_workers}, {threads}")
    root = Path(root)
    start = recipe.start_weights()
    if start is not None:
        start = _start_copy(start, recipe.init_sha256, root)
    data = root / "data"
    state_path = root / "recipe.json"
    state = json.loads(state_path.read_text()) if state_path.is_file() else None
    if state is not None and state["recipe"] != json.loads(json.dumps(recipe.to_dict())):
        raise CnnSlamError(f"{root} holds the work of recipe {state['recipe']['name']!r} with other settings, not "
                           f"{recipe.name!r}'s; pass another root")
    seconds: dict[str, float] = dict(state["seconds"]) if state else {"generate": 0.0, "fit": 0.0}
    root.mkdir(parents=True, exist_ok=True)

    def save_state() -> None:
        state_path.write_text(json.dumps({"recipe": recipe.to_dict(), "seconds": seconds}, indent=2) + "\n")

    save_state()
    t0 = time.perf_counter()
    try:
        generate_dataset(data, "train", recipe.generation, render_workers, progress)
        generate_dataset(data, "val", replace(recipe.generation, n_scenes=recipe.val_scenes), render_workers,
                         progress)
    finally:
        seconds["generate"] += time.perf_counter() - t0
        save_state()
    (data / "generation.json").write_text(json.dumps({
        "config": asdict(recipe.generation), "val_scenes": recipe.val_scenes,
        "train_frames": recipe.generation.n_scenes * recipe.generation.views_per_scene,
        "val_frames": recipe.val_scenes * recipe.generation.views_per_scene,
        "wall_time_s": round(seconds["generate"], 1), "workers": render_workers}, indent=2) + "\n")
    cfg = replace(recipe.fit, data_root=str(data), out_dir=str(root / "run"), device=device,
                  loader_workers=loader_workers, num_threads=threads,
                  init_weights=None if start is None else str(start))
    t0 = time.perf_counter()
    try:
        result = train(cfg, resume=True, progress=train_progress, on_step=on_step)
    finally:
        seconds["fit"] += time.perf_counter() - t0
        save_state()
    manifest = json.loads(result.manifest.read_text())
    manifest["recipe"] = {**recipe.to_dict(), "device": device, "render_workers": render_workers,
                          "loader_workers": loader_workers, "seconds": {k: round(v, 1) for k, v in seconds.items()}}
    result.manifest.write_text(json.dumps(manifest, indent=2) + "\n")
    return RecipeResult(data, result, seconds)


def _start_copy(path: Path, sha256: str | None, root: Path) -> Path:
    """The fine-tune's start as ``root/start.pt`` (with its manifest as ``root/start.json``), copied from ``path``
    on the first call, so that a later call resumes from the same start even if ``path`` has since been overwritten
    (e.g. the shipped default by an export). Refuses a missing start, or (with ``sha256``) one of other bytes."""
    import hashlib
    import shutil

    local = root / "start.pt"
    source = local if local.is_file() else path
    if not source.is_file():
        raise CnnSlamError(f"the recipe starts from {source}, which does not exist")
    if sha256 is not None and hashlib.sha256(source.read_bytes()).hexdigest() != sha256:
        raise CnnSlamError(f"{source} is not the recipe's start (SHA-256 {sha256}); restore those weights (git "
                           f"history of cnnslam/depthnet/weights/default.pt) or pass their file")
    if source is path:
        root.mkdir(parents=True, exist_ok=True)
        if path.with_suffix(".json").is_file():
            shutil.copyfile(path.with_suffix(".json"), root / "start.json")
        shutil.copyfile(path, root / "start.pt.tmp")
        os.replace(root / "start.pt.tmp", local)
    return local
