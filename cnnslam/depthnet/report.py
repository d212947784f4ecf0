"""The validation report's text: a Markdown table and the JSON document (pure string/dict building, no I/O)."""

from __future__ import annotations

from typing import Any

from cnnslam.depthnet.validate import TARGETS, SequenceResult, ValidationReport


def _pct(x: float) -> str:
    return f"{100 * x:.1f}"


def _row(r: SequenceResult) -> str:
    return (
        f"| {r.name} | {r.camera} | {r.frames} | {r.f_cur / r.f_tr:.3f}"
        f" | {r.raw.abs_rel:.3f} | {r.adjusted.abs_rel:.3f}"
        f" | {r.raw.rmse:.3f} | {r.adjusted.rmse:.3f} | {r.raw.delta_1_25:.1f} | {r.adjusted.delta_1_25:.1f}"
        f" | {r.raw.percent_correct:.1f} | {r.adjusted.percent_correct:.1f} | {_pct(r.semantic.pixel_accuracy)}"
        f" | {_pct(r.semantic.mean_iou)} |"
    )


def report_document(report: ValidationReport, manifest: dict[str, Any] | None, bench: dict[str, Any] | None,
                    weights: str) -> dict[str, Any]:
    """The JSON document of results/depthnet.json: validation figures, benchmark, and training facts."""
    doc: dict[str, Any] = {"weights": weights, "validation": report.to_dict(), "benchmark": bench}
    if manifest is not None:
        doc["training"] = {
            k: manifest.get(k)
            for k in ("architecture", "parameters", "train_focal", "train_size", "data_seed", "steps", "wall_time_s",
                      "validation_heldout_train_split")
        }
        data = manifest.get("data") or {}
        doc["training"]["data"] = {k: data.get(k) for k in ("train", "val", "generation")}
    return doc


def report_markdown(report: ValidationReport, manifest: dict[str, Any] | None, bench: dict[str, Any] | None,
                    weights: str, figure: str = "depthnet_samples.png") -> str:
    """results/depthnet.md: how it was measured, the table (raw vs eq. 5 adjusted), targets, speed, training."""
    o = report.overall
    met = report.targets_met()
    lines = [
        "# Depth + semantic network: validation on the test sequences",
        "",
        f"Weights: `{weights}`. Frames: {report.frames_per_sequence} evenly spaced frames per test sequence "
        "(office / living rooms with ICL-NUIM intrinsics, office rooms with TUM fr3 intrinsics: room styles, scenes "
        "and cameras the network never saw; it was trained on other room styles with NYU intrinsics). Depth metrics "
        "pooled over every pixel with ground truth; \"raw\" = the network's output, \"eq. 5\" = after the "
        "focal-length adjustment D = (f_cur / f_tr) D~ (CNN-SLAM eq. 5, the paper's Fig. 3 (a) vs (b)), with f = "
        "(fx + fy) / 2 at 320x240. Within 10 % = CNN-SLAM's \"correct depth\" over all valid pixels of the dense map."
        + ("" if report.camera_effects == "clean" else
           f" Images seen through the world's `{report.camera_effects}` camera (`sim_envs/sensor/camera_effects.py`)."),
        "",
        "| sequence | camera | frames | f_cur/f_tr | AbsRel raw | AbsRel eq. 5 | RMSE raw [m] | RMSE eq. 5 [m] "
        "| δ<1.25 raw [%] | δ<1.25 eq. 5 [%] | within 10 % raw [%] | within 10 % eq. 5 [%] | pixel acc. [%] "
        "| mean IoU [%] |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    lines += [_row(r) for r in report.sequences]
    lines += [_row(r).replace(f"| {r.name} |", f"| **{r.name} (all)** |") for r in report.groups.values()]
    lines += [_row(o).replace("| all |", "| **all** |")]
    lines += ["", "## Targets (overall, after eq. 5)", "", "| metric | target | measured | met |", "|---|---|---|---|"]
    measured = {"abs_rel": f"{o.adjusted.abs_rel:.3f}", "percent_correct": f"{o.adjusted.percent_correct:.1f} %",
                "pixel_accuracy": f"{_pct(o.semantic.pixel_accuracy)} %"}
    for key, (op, bound) in TARGETS.items():
        shown = {"abs_rel": f"{bound:.2f}", "percent_correct": f"{bound:.0f} %"}.get(key, f"{100 * bound:.0f} %")
        lines.append(f"| {key} | {op} {shown} | {measured[key]} | {'yes' if met[key] else 'NO'} |")
    iou = ", ".join(f"{name} {_pct(v)}" for name, v in zip(
        ("floor", "vertical", "large", "small"), o.semantic.iou, strict=False))
    lines += ["", f"Per-class IoU [%] (all frames): {iou}.", ""]
    if bench is not None:
        lines += [
            "## Inference speed",
            "",
            f"`python -m cnnslam.depthnet.bench`: {bench['median_ms']:.1f} ms per {bench['width']}x{bench['height']} "
            f"frame (median of {bench['repeats']} warm runs; mean {bench['mean_ms']:.1f}, min {bench['min_ms']:.1f}) "
            f"on {bench['threads']} CPU threads, {bench['parameters'] / 1e6:.2f} M parameters. Target: <= 50 ms.",
            "",
        ]
    if manifest is not None:
        arch = manifest.get("architecture", {})
        first = _first_stage(manifest)  # the data line describes the run from scratch; fine-tunes say theirs
        data = (first.get("data") or {}).get("train") or {}
        gen = (first.get("data") or {}).get("generation") or {}
        held = manifest.get("validation_heldout_train_split") or {}
        lines += [
            "## Training",
            "",
            f"- Network: FCRN-style, ResNet-{arch.get('trunk_depth')} trunk of base width {arch.get('base_width')}, "
            f"4 up-projection blocks (fast up-convolution){' with trunk skip connections' if arch.get('skips') else ''}"
            f", dropout {arch.get('dropout')}, a shared decoder with a depth head "
            f"({'exp: log depth' if arch.get('depth_activation') == 'exp' else 'softplus'}) and a 4-class semantic "
            f"head; {manifest.get('parameters', 0) / 1e6:.2f} M "
            f"parameters, trained from scratch{' then fine-tuned' if manifest.get('initialised_from') else ''}.",
            f"- Data: {data.get('frames')} frames of {data.get('shards')} rooms of the training styles "
            f"({', '.join(sorted((data.get('frames_per_style') or {}).keys()))}), scene seeds "
            f"{data.get('scene_seeds')}, rendered with NYU intrinsics at {data.get('stored_size')}, fed to the network "
            f"at {data.get('image_size')} (area-averaged, as the predictor does); data seed "
            f"{first.get('data_seed')}; generated in {gen.get('wall_time_s', 'n/a')} s on {gen.get('workers')} "
            "processes.",
            *_optimisation_lines(manifest),
            f"- Training focal length f_tr = {manifest.get('train_focal', 0):.3f} px at {manifest.get('train_size')}.",
            f"- Held-out training-split rooms: AbsRel {held.get('abs_rel', float('nan')):.3f}, within 10 % "
            f"{_pct(held.get('within_10pct', float('nan')))} %, pixel accuracy "
            f"{_pct(held.get('pixel_accuracy', float('nan')))} %.",
            "",
        ]
    lines += [
        "## Samples",
        "",
        f"![samples]({figure})",
        "",
        "Columns: input, predicted depth after eq. 5, ground truth, relative error (blue 0 to red >= 50 %, black = no "
        "ground truth), predicted labels, ground-truth labels (brown floor, light blue vertical structure, orange "
        "furniture, pink objects).",
        "",
    ]
    return "\n".join(lines)


def _first_stage(manifest: dict[str, Any]) -> dict[str, Any]:
    """The manifest of the run from scratch at the root of a chain of fine-tunes (``initialised_from``)."""
    start = (manifest.get("initialised_from") or {}).get("manifest")
    return _first_stage(start) if start else manifest


def _stage_data(manifest: dict[str, Any]) -> str:
    """A fine-tune's training data in a few words: frames, rooms, data seed, focal-length range when varied."""
    data = (manifest.get("data") or {}).get("train") or {}
    lo, hi = data.get("focal_scale") or (1.0, 1.0)
    focal = f", focal length x {lo:.2f}..{hi:.2f} per room (depth read as D / s)" if (lo, hi) != (1.0, 1.0) else ""
    seed = manifest.get("data_seed")
    return f" on {data.get('frames')} frames of {data.get('shards')} rooms (data seed {seed}{focal})"


def _optimisation_lines(manifest: dict[str, Any]) -> list[str]:
    """One line per training stage: the run that started from scratch first, then any fine-tune on top of it."""
    start = (manifest.get("initialised_from") or {}).get("manifest")
    lines = _optimisation_lines(start) if start else []
    train = manifest.get("training") or {}
    crop = tuple((train.get("augment") or {}).get("crop", ()))
    size = tuple(reversed(manifest.get("train_size") or ()))
    what = "full images" if crop == size else f"random {crop} crops"
    schedule = ("constant" if train.get("lr") == train.get("min_lr") and not train.get("warmup_steps")
                else "warm-up, cosine decay")
    stage = f"Fine-tune from {manifest['initialised_from']['weights']}" if start else "Optimisation"
    space = "log depth" if train.get("depth_space") == "log" else "depth"
    loss = f"berHu (c = 0.2 max |error| per batch) on {space}"
    if train.get("silog_weight"):
        loss += f" + {train['silog_weight']} x scale-invariant log loss"
    if train.get("gradient_weight"):
        loss += f" + {train['gradient_weight']} x log-depth gradient matching"
    env = manifest.get("environment") or {}
    where = (f"one {env['device']}" if env.get("device") and env.get("device") != "cpu"
             else f"{env.get('threads')} CPU threads")
    lines.append(
        f"- {stage}: {manifest.get('steps')} steps of batch {train.get('batch_size')} {what}"
        f"{_stage_data(manifest) if start else ''}, AdamW lr "
        f"{train.get('lr')} ({schedule}), {loss} + {train.get('semantic_weight')} x "
        f"cross-entropy; {manifest.get('wall_time_s', 0) / 3600:.2f} h on {where}.")
    return lines
