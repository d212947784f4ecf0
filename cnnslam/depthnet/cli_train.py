"""``cnnslam train``: generate the training data, train the depth network, validate it, ship it.

    cnnslam train generate-data [--root data/depthnet] [--scenes 1200] [--views 20] [--val-scenes 20] [--workers 2]
                                [--focal-scale LO HI] [--camera-effects PRESET...]   # through the world's camera
                                [--lighting flat lit]   # rooms with lamps, shadows, highlights (one drawn per room)
    cnnslam train fit [--data data/depthnet] [--out data/depthnet/run] [--steps 16000] [--batch 16] ... [--export]
    cnnslam train validate [--weights W] [--frames 40] [--camera PRESET] [--results results] [--update-manifest]
    cnnslam train validate-folder FOLDER... [--frames 100] [--window 100]   # real frames -> results/depthnet_real.md
    cnnslam train export [--run data/depthnet/run]
    cnnslam train recipe [--recipe shipped-v2|shipped-v3] [--root DIR]   # data + fit; call again to resume
    cnnslam train export-onnx [--weights W] [--out data/depthnet/export/depthnet.onnx] [--out net.pt]

``fit`` resumes from ``<out>/checkpoint.pt`` when it exists (``--restart`` starts over); ``--export`` (or ``export``)
copies the run's weights and manifest to ``cnnslam/depthnet/weights/default.{pt,json}``, the shipped default, the
manifest recording the weights' SHA-256 (checked whenever they are loaded).
``validate`` writes ``results/depthnet.md``, ``results/depthnet.json`` and ``results/depthnet_samples.png``.

The shipped weights were made in two stages. First the defaults: ``generate-data --val-scenes 20`` (11 min on 2
cores), ``fit`` (1.54 h on 2 cores; that run was resumed twice with another ``--steps``, 14000, then 12000 from step
7250, then 16000 from step 8000, which bends its cosine schedule; a run from scratch with ``--steps 16000`` follows
the plain schedule). Then a fine-tune on full images, because a network trained on 96x128 crops predicted 0.96 of
the true depth on full 120x160 images (1.00 on crops), which eq. 5 then carried into every key-frame::

    cnnslam train fit --init-weights data/depthnet/run/weights.pt --crop 120 160 --lr 1e-4 --min-lr 1e-4 \
        --warmup 0 --steps 400 --seed 7 --out data/depthnet/finetune    # 3 min on 2 cores

Then a second fine-tune on full images of new views of 400 training rooms, each rendered with the NYU focal length
times a factor in [0.8, 1.25] and its depth read as D / s (the depth the training camera would report for that
image: eq. 5's premise), 2 + 8 min on 2 cores::

    cnnslam train generate-data --root data/depthnet/focal --scenes 400 --val-scenes 20 --seed 1 \
        --focal-scale 0.8 1.25
    cnnslam train fit --data data/depthnet/focal --init-weights data/depthnet/finetune/weights.pt --crop 120 160 \
        --lr 1e-4 --min-lr 1e-4 --warmup 0 --steps 1200 --seed 7 --val-every 400 --out data/depthnet/focalft --export
    cnnslam train validate --update-manifest

The shipped manifest records every stage (``initialised_from``, with the start's SHA-256).

A fine-tune on images through the world's cameras (``--camera-effects clean kinect hard``, 400 rooms, seed 2, the
same fit as the last stage) was measured and not shipped: better on every simulated camera, worse on real frames
(docs/benchmarks.md, "What limits CNN-SLAM on real frames"). So was one on flat and lit rooms (``--lighting flat
lit``, seed 4): more real pixels within 10 %, but further off at the real frames' high-gradient pixels, and CNN-SLAM
worse on them (same section).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import asdict, replace
from pathlib import Path
from typing import Any

from cnnslam.depthnet.data import AugmentConfig, GenerationConfig, generate_dataset
from cnnslam.depthnet.model import ModelConfig
from cnnslam.depthnet.train import TrainConfig, train
from cnnslam.depthnet.weights_io import DEFAULT_MANIFEST, DEFAULT_WEIGHTS, export_weights
from cnnslam.errors import CnnSlamError
from sim_envs.sensor.camera_effects import DEFAULT_CAMERA_EFFECTS


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Subcommands generate-data / fit / validate / export."""
    sub = parser.add_subparsers(dest="action", metavar="ACTION", required=True)

    g = sub.add_parser("generate-data", help="render the training and validation shards (resumable)")
    g.add_argument("--root", type=Path, default=Path("data/depthnet"))
    g.add_argument("--scenes", type=int, default=GenerationConfig.n_scenes, help="training rooms")
    g.add_argument("--views", type=int, default=GenerationConfig.views_per_scene, help="views per room")
    g.add_argument("--val-scenes", type=int, default=20, help="held-out rooms of the training styles")
    g.add_argument("--seed", type=int, default=0, help="data seed")
    g.add_argument("--workers", type=int, default=2, help="render processes (0: in this process)")
    g.add_argument("--focal-scale", type=float, nargs=2, default=list(GenerationConfig.focal_scale),
                   metavar=("LO", "HI"), help="per-room focal-length factor range (log-uniform); depth read as D / s")
    g.add_argument("--camera-effects", nargs="+", default=list(GenerationConfig.camera_effects), metavar="PRESET",
                   help="the world's camera, one preset drawn per room (clean, kinect, hard, EFFECT:S): images as "
                        "that camera delivers them, moving hand-held (default: clean, the renderer's bytes)")
    g.add_argument("--lighting", nargs="+", default=list(GenerationConfig.lighting), metavar="LIGHTING",
                   help="the rooms' lighting, one drawn per room: flat (default) or lit (lamps, shadows, bright "
                        "windows, highlights; mujoco renderer)")
    g.add_argument("--detail", nargs="+", default=list(GenerationConfig.detail), metavar="DETAIL",
                   help="the rooms' detail, one drawn per room: standard (default) or rich (clutter, texture detail)")

    f = sub.add_parser("fit", help="train (or resume) and write weights + manifest")
    d = TrainConfig()
    f.add_argument("--data", type=Path, default=Path(d.data_root))
    f.add_argument("--out", type=Path, default=Path(d.out_dir))
    f.add_argument("--steps", type=int, default=d.steps)
    f.add_argument("--batch", type=int, default=d.batch_size)
    f.add_argument("--crop", type=int, nargs=2, default=list(d.augment.crop), metavar=("H", "W"),
                   help="random crop, pixels at the network's resolution")
    f.add_argument("--downsample", type=int, default=d.downsample, choices=(1, 2, 4),
                   help="the network works at 1/downsample of the rendered images")
    f.add_argument("--lr", type=float, default=d.lr)
    f.add_argument("--min-lr", type=float, default=d.min_lr, help="end of the cosine decay (= --lr: constant)")
    f.add_argument("--init-weights", type=Path, default=None,
                   help="start from these weights (same architecture) instead of a random init: a fine-tune")
    f.add_argument("--semantic-weight", type=float, default=d.semantic_weight)
    f.add_argument("--trunk-depth", type=int, default=d.model.trunk_depth, choices=(18, 34, 50))
    f.add_argument("--base-width", type=int, default=d.model.base_width)
    f.add_argument("--dropout", type=float, default=d.model.dropout)
    f.add_argument("--skips", action=argparse.BooleanOptionalAction, default=d.model.skips,
                   help="trunk-to-decoder skip connections (ours, not FCRN)")
    f.add_argument("--depth-activation", choices=("softplus", "exp"), default=d.model.depth_activation)
    f.add_argument("--depth-space", choices=("linear", "log"), default=d.depth_space,
                   help="berHu on depth (FCRN) or on log depth")
    f.add_argument("--silog-weight", type=float, default=d.silog_weight,
                   help="weight of the scale-invariant log loss (Eigen et al.; 0 = off)")
    f.add_argument("--gradient-weight", type=float, default=d.gradient_weight,
                   help="weight of the multi-scale gradient-matching loss on log depth (MiDaS; 0 = off)")
    f.add_argument("--camera-augment", type=float, default=d.augment.p_camera, metavar="P",
                   help="share of samples through a camera pipeline (vignetting, motion blur, shot noise, JPEG)")
    f.add_argument("--device", choices=("cpu", "cuda"), default=d.device, help="where to train (cuda: a GPU)")
    f.add_argument("--loader-workers", type=int, default=d.loader_workers,
                   help="processes preparing the coming batches (1: one thread)")
    f.add_argument("--warmup", type=int, default=d.warmup_steps)
    f.add_argument("--seed", type=int, default=d.seed)
    f.add_argument("--threads", type=int, default=d.num_threads)
    f.add_argument("--val-every", type=int, default=d.val_every)
    f.add_argument("--checkpoint-every", type=int, default=d.checkpoint_every)
    f.add_argument("--restart", action="store_true", help="ignore an existing checkpoint and start over")
    f.add_argument("--no-progress", action="store_true", help="no progress bar")
    f.add_argument("--export", action="store_true", help="copy the result to the shipped default weights")

    v = sub.add_parser("validate", help="score weights on the test sequences; write results/depthnet.*")
    v.add_argument("--weights", type=Path, default=DEFAULT_WEIGHTS)
    v.add_argument("--frames", type=int, default=40, help="frames per test sequence")
    v.add_argument("--camera", default=DEFAULT_CAMERA_EFFECTS, metavar="PRESET",
                   help="the world's camera the test sequences are seen through (clean, kinect, hard; default "
                        f"{DEFAULT_CAMERA_EFFECTS}, the one the suites score)")
    v.add_argument("--results", type=Path, default=Path("results"))
    v.add_argument("--threads", type=int, default=2)
    v.add_argument("--update-manifest", action="store_true",
                   help="store the figures in the manifest beside the weights (<weights>.json or manifest.json)")

    r = sub.add_parser("validate-folder", help="score weights on real RGB-D folders' frames; write "
                                                 "results/depthnet_real.{md,json}")  # fmt: skip
    r.add_argument("folders", nargs="+", type=Path, help="RGB-D folders (TUM, ICL-NUIM, 7-Scenes layouts)")
    r.add_argument("--weights", type=Path, default=DEFAULT_WEIGHTS)
    r.add_argument("--frames", type=int, default=100, help="evenly spaced frames per folder")
    r.add_argument("--window", type=int, default=100,
                   help="consecutive frames in the middle of each folder, for the scale's frame-to-frame change "
                        "(0: none)")
    r.add_argument("--results", type=Path, default=Path("results"))
    r.add_argument("--threads", type=int, default=2)

    e = sub.add_parser("export", help="copy a run's weights + manifest to the shipped default")
    e.add_argument("--run", type=Path, default=Path(d.out_dir))

    eo = sub.add_parser("export-onnx", help="write the network as an ONNX (.onnx) and/or TorchScript (.pt) model file "
                                            "with its sidecar <file>.json, for a methods table's predictor")
    eo.add_argument("--weights", type=Path, default=DEFAULT_WEIGHTS)
    eo.add_argument("--out", type=Path, action="append", default=None, metavar="FILE",
                    help="model file, format by extension (.onnx; .pt .pth .ts .torchscript: TorchScript); "
                         "repeatable; default data/depthnet/export/depthnet.onnx")

    ds = sub.add_parser("data-statistics", help="image statistics and depth distributions of the training rooms, the "
                                                "simulated test sequences and real folders -> results/depthnet_data.md")
    ds.add_argument("folders", nargs="*", type=Path, help="real RGB-D folders to compare with (test data)")
    ds.add_argument("--root", type=Path, default=Path("data/depthnet/shipped"),
                    help="the recipe's folder; its first --rooms training rooms are rendered there if missing")
    ds.add_argument("--rooms", type=int, default=40, help="training rooms sampled (the recipe's first ones)")
    ds.add_argument("--frames", type=int, default=200, help="frames per domain")
    ds.add_argument("--camera", default=DEFAULT_CAMERA_EFFECTS, metavar="PRESET",
                    help="the world's camera of the simulated test sequences")
    ds.add_argument("--results", type=Path, default=Path("results"))

    rc = sub.add_parser("recipe", help="retrain the shipped network from nothing: render its data, fit (resumable)")
    rc.add_argument("--recipe", default="shipped-v2", metavar="NAME",
                    help="shipped-v2 (the shipped network, from nothing) or shipped-v3 (its close-range fine-tune)")
    rc.add_argument("--root", type=Path, default=None,
                    help="folder of the recipe's data (data/) and run (run/); a second call resumes the work there "
                         "(default data/depthnet/shipped, data/depthnet/<NAME> for other recipes)")
    rc.add_argument("--device", choices=("cpu", "cuda"), default="cpu", help="where to train (cuda: a GPU)")
    rc.add_argument("--render-workers", type=int, default=2, help="render processes")
    rc.add_argument("--loader-workers", type=int, default=1, help="processes preparing the coming batches")
    rc.add_argument("--threads", type=int, default=2, help="torch intra-op threads")
    rc.add_argument("--no-progress", action="store_true", help="no progress bars")
    rc.add_argument("--export", action="store_true", help="copy the result to the shipped default weights")


def _progress(desc: str) -> Any:
    from tqdm import tqdm

    return lambda it, total: tqdm(it, total=total, desc=desc, dynamic_ncols=True)


def _generate(args: argparse.Namespace) -> int:
    cfg = GenerationConfig(n_scenes=args.scenes, views_per_scene=args.views, data_seed=args.seed,
                           focal_scale=tuple(args.focal_scale), camera_effects=tuple(args.camera_effects),
                           lighting=tuple(args.lighting), detail=tuple(args.detail))
    args.root.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    train_dirs = generate_dataset(args.root, "train", cfg, args.workers, _progress("train shards"))
    val_cfg = replace(cfg, n_scenes=args.val_scenes)
    val_dirs = generate_dataset(args.root, "val", val_cfg, args.workers, _progress("val shards"))
    wall = time.perf_counter() - t0
    gen_path = args.root / "generation.json"
    previous = json.loads(gen_path.read_text()) if gen_path.is_file() else {}
    record = {
        "config": asdict(cfg),
        "val_scenes": args.val_scenes,
        "train_frames": len(train_dirs) * cfg.views_per_scene,
        "val_frames": len(val_dirs) * cfg.views_per_scene,
        # total over resumed invocations of the same configuration
        "wall_time_s": round(wall + (previous.get("wall_time_s", 0.0) if previous.get("config") == asdict(cfg)
                                     else 0.0), 1),
        "workers": args.workers,
    }
    gen_path.write_text(json.dumps(record, indent=2) + "\n")
    print(f"{len(train_dirs)} training and {len(val_dirs)} validation shards under {args.root} "
          f"({record['train_frames']} + {record['val_frames']} frames); this run {wall:.0f} s")
    return 0


def _export(run: Path) -> None:
    try:
        doc = export_weights(run / "weights.pt", run / "manifest.json", DEFAULT_WEIGHTS, DEFAULT_MANIFEST)
    except CnnSlamError as exc:
        raise SystemExit(f"cnnslam train export: error: {exc}") from exc
    print(f"exported {run / 'weights.pt'} -> {DEFAULT_WEIGHTS} ({doc['weights_bytes'] / 1e6:.1f} MB, "
          f"sha256 {doc['weights_sha256']})")


def _export_model(args: argparse.Namespace) -> int:
    from cnnslam.depth.model_file import model_file_kind
    from cnnslam.depthnet.export_model import export_model_file

    outs = args.out or [Path("data/depthnet/export/depthnet.onnx")]
    try:
        for out in outs:  # every extension checked before any file is written
            model_file_kind(out)
        for out in outs:
            done = export_model_file(out, args.weights)
            print(f"wrote {done.path} ({done.kind}, {done.bytes / 1e6:.1f} MB) and {done.sidecar}")
    except CnnSlamError as exc:
        print(f"cnnslam train export-onnx: error: {exc}", file=sys.stderr)
        return 2
    return 0


def _fit(args: argparse.Namespace) -> int:
    d = TrainConfig()
    cfg = replace(
        d,
        data_root=str(args.data),
        out_dir=str(args.out),
        steps=args.steps,
        batch_size=args.batch,
        lr=args.lr,
        min_lr=args.min_lr,
        init_weights=None if args.init_weights is None else str(args.init_weights),
        semantic_weight=args.semantic_weight,
        seed=args.seed,
        num_threads=args.threads,
        val_every=args.val_every,
        checkpoint_every=args.checkpoint_every,
        downsample=args.downsample,
        depth_space=args.depth_space,
        warmup_steps=args.warmup,
        silog_weight=args.silog_weight,
        gradient_weight=args.gradient_weight,
        device=args.device,
        loader_workers=args.loader_workers,
        model=ModelConfig(trunk_depth=args.trunk_depth, base_width=args.base_width, dropout=args.dropout,
                          skips=args.skips, depth_activation=args.depth_activation),
        augment=replace(AugmentConfig(), crop=(args.crop[0], args.crop[1]), p_camera=args.camera_augment),
    )
    result = train(cfg, resume=not args.restart, progress=not args.no_progress)
    v = result.validation
    print(f"trained {result.steps} steps in {result.wall_time_s / 3600:.2f} h; held-out val: AbsRel "
          f"{v['abs_rel']:.3f}, within 10 % {100 * v['within_10pct']:.1f} %, pixel acc. {100 * v['pixel_accuracy']:.1f}"
          f" %; weights {result.weights}")
    if args.export:
        _export(Path(args.out))
    return 0


def _record(outputs: list[Path], action: str, modules: list[str], inputs: list[Path], folders: list[Path] = ()
            ) -> None:
    """The provenance manifest of files ``action`` wrote (:func:`slamcommon.provenance.record_outputs`): the code
    of ``modules``, the ``inputs``' SHA-256 (the weights), the real ``folders``' content fingerprints."""
    from sim_envs.folders.folder_layouts import folder_fingerprint
    from slamcommon.provenance import record_outputs

    record_outputs(outputs, f"cnnslam train {action}", modules, inputs,
                   {f: folder_fingerprint(f)["sha256"] for f in folders})


def _validate_folder(args: argparse.Namespace) -> int:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from cnnslam.depthnet.plots import plot_scale_over_frames
    from cnnslam.depthnet.predict import load_predictor
    from cnnslam.depthnet.validate import folder_validation_markdown, validate_folder
    from sim_envs.errors import SimEnvError
    from sim_envs.folders.datasets import load_rgbd_folder

    for name, value, least in (("--frames", args.frames, 1), ("--window", args.window, 0)):
        if value < least:
            print(f"cnnslam train validate-folder: error: {name} must be >= {least}, got {value}", file=sys.stderr)
            return 2
    predictor = load_predictor(args.weights, num_threads=args.threads)
    results = []
    for folder in args.folders:
        try:
            source = load_rgbd_folder(folder)
        except SimEnvError as exc:
            print(f"cnnslam train validate-folder: error: {exc}", file=sys.stderr)
            return 2
        results.append(validate_folder(predictor, source, args.frames, progress=_progress(f"validate {folder.name}"),
                                       window=args.window))
    sim_json = args.results / "depthnet.json"
    simulated = json.loads(sim_json.read_text())["validation"]["overall"] if sim_json.is_file() else None
    args.results.mkdir(parents=True, exist_ok=True)
    (args.results / "depthnet_real.md").write_text(folder_validation_markdown(results, simulated))
    (args.results / "depthnet_real.json").write_text(json.dumps([r.to_dict() for r in results], indent=2) + "\n")
    fig, axes = plt.subplots(len(results), 1, figsize=(8, 2.6 * len(results) + 0.4), squeeze=False)
    for ax, r in zip(axes[:, 0], results, strict=True):
        plot_scale_over_frames(ax, r)
    fig.tight_layout()
    fig.savefig(args.results / "depthnet_real_scale.png", dpi=80)
    plt.close(fig)
    _record([args.results / f"depthnet_real{s}" for s in (".md", ".json", "_scale.png")], "validate-folder",
            ["cnnslam.depthnet.plots", "cnnslam.depthnet.predict", "cnnslam.depthnet.validate",
             "sim_envs.folders.datasets"],
            [args.weights, *([sim_json] if sim_json.is_file() else [])], args.folders)
    print(f"wrote {args.results / 'depthnet_real.md'} and {args.results / 'depthnet_real.json'}")
    return 0


def _validate(args: argparse.Namespace) -> int:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from cnnslam.depthnet.bench import benchmark
    from cnnslam.depthnet.plots import plot_sample_row
    from cnnslam.depthnet.predict import load_predictor
    from cnnslam.depthnet.report import report_document, report_markdown
    from cnnslam.depthnet.validate import validate_sequences

    predictor = load_predictor(args.weights, num_threads=args.threads)
    manifest_path = DEFAULT_MANIFEST if args.weights == DEFAULT_WEIGHTS else args.weights.parent / "manifest.json"
    manifest = json.loads(manifest_path.read_text()) if manifest_path.is_file() else None
    report = validate_sequences(predictor, frames_per_sequence=args.frames, sample_every=2,
                                progress=_progress("validate"), camera_effects=args.camera)
    try:  # the repository-relative name where it has one, so the manifest names no machine's folder
        weights_label = str(args.weights.resolve().relative_to(Path.cwd()))
    except ValueError:
        weights_label = str(args.weights)
    bench = asdict(benchmark(predictor, weights_label=weights_label))
    args.results.mkdir(parents=True, exist_ok=True)
    doc = report_document(report, manifest, bench, weights_label)
    (args.results / "depthnet.json").write_text(json.dumps(doc, indent=2) + "\n")
    (args.results / "depthnet.md").write_text(report_markdown(report, manifest, bench, weights_label))
    n = len(report.samples)
    if n:
        fig, axes = plt.subplots(n, 6, figsize=(16, 2.3 * n + 0.4), squeeze=False)
        for k, sample in enumerate(report.samples):
            plot_sample_row(axes[k], sample, titles=(k == 0))
        fig.tight_layout()
        fig.savefig(args.results / "depthnet_samples.png", dpi=80)
        plt.close(fig)
    _record([args.results / f"depthnet.{s}" for s in ("json", "md")] + [args.results / "depthnet_samples.png"],
            "validate", ["cnnslam.depthnet.bench", "cnnslam.depthnet.plots", "cnnslam.depthnet.predict",
                         "cnnslam.depthnet.report", "cnnslam.depthnet.validate"], [args.weights])
    if args.update_manifest and manifest is not None:
        manifest["validation_test_sequences"] = {
            "overall": doc["validation"]["overall"],
            "groups": doc["validation"]["groups"],
            "frames_per_sequence": args.frames,
            "targets_met": doc["validation"]["targets_met"],
        }
        manifest["benchmark"] = bench
        manifest_path.write_text(json.dumps(manifest, indent=2) + "\n")
    o = report.overall
    print(f"test sequences, {o.frames} frames: AbsRel raw {o.raw.abs_rel:.3f} / eq. 5 {o.adjusted.abs_rel:.3f}; "
          f"within 10 % raw {o.raw.percent_correct:.1f} % / eq. 5 {o.adjusted.percent_correct:.1f} %; "
          f"pixel acc. {100 * o.semantic.pixel_accuracy:.1f} %, mIoU {100 * o.semantic.mean_iou:.1f} %; "
          f"inference {bench['median_ms']:.1f} ms/frame; targets met: {report.targets_met()}")
    return 0


def _data_statistics(args: argparse.Namespace) -> int:
    from cnnslam.depthnet.data import generate_dataset
    from cnnslam.depthnet.data_report import (
        data_statistics_markdown,
        domain_statistics,
        source_frames,
        training_frames,
    )
    from cnnslam.depthnet.recipe import SHIPPED
    from cnnslam.depthnet.validate import VALIDATION_SEQUENCES
    from sim_envs.errors import SimEnvError
    from sim_envs.folders.datasets import load_rgbd_folder
    from sim_envs.sequences import get_sequence, with_camera
    from sim_envs.sources.simsource import SimulatedSequence

    try:
        folders = [load_rgbd_folder(f) for f in args.folders]
    except SimEnvError as exc:
        print(f"cnnslam train data-statistics: error: {exc}", file=sys.stderr)
        return 2
    data = args.root / "data"
    generate_dataset(data, "train", replace(SHIPPED.generation, n_scenes=args.rooms), 2, _progress("rooms"))
    rows = [domain_statistics(f"training rooms ({SHIPPED.name}, first {args.rooms})",
                              training_frames(data, args.frames))]
    per_seq = max(2, args.frames // len(VALIDATION_SEQUENCES))
    sim = (pair for name in VALIDATION_SEQUENCES
           for pair in source_frames(SimulatedSequence(with_camera(get_sequence(name), args.camera)), per_seq))
    rows.append(domain_statistics(f"simulated test sequences ({args.camera})", sim))
    rows += [domain_statistics(f"{src.name} (real)", source_frames(src, args.frames)) for src in folders]
    args.results.mkdir(parents=True, exist_ok=True)
    out = args.results / "depthnet_data.md"
    out.write_text(data_statistics_markdown(rows))
    _record([out], "data-statistics", ["cnnslam.depthnet.data", "cnnslam.depthnet.data_report",
                                       "cnnslam.depthnet.recipe", "cnnslam.depthnet.validate",
                                       "sim_envs.folders.datasets", "sim_envs.sequences", "sim_envs.sources.simsource"],
            [], args.folders)
    print(f"wrote {out}")
    return 0


def _recipe(args: argparse.Namespace) -> int:
    from cnnslam.depthnet.recipe import SHIPPED, get_recipe, run_recipe

    try:
        recipe = get_recipe(args.recipe)
        root = args.root or Path("data/depthnet/shipped" if recipe is SHIPPED else f"data/depthnet/{recipe.name}")
        res = run_recipe(recipe, root, device=args.device, render_workers=args.render_workers,
                         loader_workers=args.loader_workers, threads=args.threads,
                         progress=None if args.no_progress else _progress("shards"),
                         train_progress=not args.no_progress)
    except CnnSlamError as exc:
        print(f"cnnslam train recipe: error: {exc}", file=sys.stderr)
        return 2
    v = res.fit.validation
    print(f"recipe {recipe.name}: data {res.seconds['generate'] / 60:.1f} min, fit {res.seconds['fit'] / 3600:.2f} h "
          f"({res.fit.steps} steps, {args.device}); held-out val: AbsRel {v['abs_rel']:.3f}, within 10 % "
          f"{100 * v['within_10pct']:.1f} %; weights {res.fit.weights}")
    if args.export:
        _export(res.fit.weights.parent)
    return 0


def run(args: argparse.Namespace) -> int:
    """Dispatch the action."""
    if args.action == "recipe":
        return _recipe(args)
    if args.action == "data-statistics":
        return _data_statistics(args)
    if args.action == "generate-data":
        return _generate(args)
    if args.action == "fit":
        return _fit(args)
    if args.action == "validate":
        return _validate(args)
    if args.action == "validate-folder":
        return _validate_folder(args)
    if args.action == "export-onnx":
        return _export_model(args)
    _export(args.run)
    return 0
