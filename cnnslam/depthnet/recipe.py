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
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable, Iterator
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

from cnnslam.depthnet.data import AugmentConfig, GenerationConfig, generate_dataset
from cnnslam.depthnet.train import TrainConfig, TrainResult, train
from cnnslam.errors import CnnSlamError

Progress = Callable[[Iterator[Any], int], Iterator[Any]]


@dataclass(frozen=True)
class Recipe:
    """Data, validation rooms and training of one network (see the module docstring)."""

    generation: GenerationConfig
    val_scenes: int
    fit: TrainConfig
    name: str = "recipe"

    def to_dict(self) -> dict[str, Any]:
        """JSON-serialisable form (the manifest records it)."""
        return {"name": self.name, "generation": asdict(self.generation), "val_scenes": self.val_scenes,
                "fit": self.fit.to_dict()}


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
) -> RecipeResult:
    """Render the recipe's data under ``root/data`` and train under ``root/run`` (both resumable).

    device: "cpu" or "cuda"; render_workers: render processes; loader_workers: batch processes of the fit (1: one
    thread); threads: torch's intra-op threads. Returns the run's weights and manifest (``root/run``).
    """
    if render_workers < 0 or loader_workers < 1 or threads < 1:
        raise CnnSlamError(f"need render_workers >= 0, loader_workers >= 1 and threads >= 1, got {render_workers}, "
                           f"{loader_workers}, {threads}")
    root = Path(root)
    data = root / "data"
    seconds: dict[str, float] = {}
    t0 = time.perf_counter()
    generate_dataset(data, "train", recipe.generation, render_workers, progress)
    generate_dataset(data, "val", replace(recipe.generation, n_scenes=recipe.val_scenes), render_workers, progress)
    seconds["generate"] = time.perf_counter() - t0
    (data / "generation.json").write_text(json.dumps({
        "config": asdict(recipe.generation), "val_scenes": recipe.val_scenes,
        "train_frames": recipe.generation.n_scenes * recipe.generation.views_per_scene,
        "val_frames": recipe.val_scenes * recipe.generation.views_per_scene,
        "wall_time_s": round(seconds["generate"], 1), "workers": render_workers}, indent=2) + "\n")
    cfg = replace(recipe.fit, data_root=str(data), out_dir=str(root / "run"), device=device,
                  loader_workers=loader_workers, num_threads=threads)
    t0 = time.perf_counter()
    result = train(cfg, resume=True, progress=train_progress)
    seconds["fit"] = time.perf_counter() - t0
    manifest = json.loads(result.manifest.read_text())
    manifest["recipe"] = {**recipe.to_dict(), "device": device, "render_workers": render_workers,
                          "loader_workers": loader_workers, "seconds": {k: round(v, 1) for k, v in seconds.items()}}
    result.manifest.write_text(json.dumps(manifest, indent=2) + "\n")
    return RecipeResult(data, result, seconds)
