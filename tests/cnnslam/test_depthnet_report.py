"""The validation report's training section: one line per stage of a chain of fine-tunes, each with its data."""

from __future__ import annotations

from typing import Any

from cnnslam.depthnet.report import _first_stage, _optimisation_lines


def _manifest(steps: int, crop: list[int], start: dict[str, Any] | None, focal: list[float] | None = None,
              frames: int = 100, seed: int = 0) -> dict[str, Any]:
    train = {"frames": frames, "shards": frames // 20}
    if focal is not None:
        train["focal_scale"] = focal
    return {
        "steps": steps, "train_size": [160, 120], "data_seed": seed, "data": {"train": train},
        "training": {"augment": {"crop": crop}, "batch_size": 16, "lr": 1e-4, "min_lr": 1e-4, "warmup_steps": 0,
                     "depth_space": "log", "semantic_weight": 0.5},
        "wall_time_s": 360.0, "environment": {"threads": 2}, "initialised_from": start,
    }


def test_every_stage_gets_a_line_with_its_data() -> None:
    first = _manifest(1000, [96, 128], None, frames=2000)
    first["training"].update(lr=1e-3, min_lr=1e-5, warmup_steps=500)
    second = _manifest(400, [120, 160], {"weights": "a.pt", "manifest": first})
    third = _manifest(1200, [120, 160], {"weights": "b.pt", "manifest": second}, focal=[0.8, 1.25], frames=8000,
                      seed=1)
    lines = _optimisation_lines(third)
    assert len(lines) == 3
    assert lines[0].startswith("- Optimisation: 1000 steps of batch 16 random (96, 128) crops, AdamW lr 0.001")
    assert "warm-up, cosine decay" in lines[0] and " rooms " not in lines[0]  # the data line covers stage one
    assert lines[1].startswith("- Fine-tune from a.pt: 400 steps of batch 16 full images on 100 frames of 5 rooms")
    assert "(constant)" in lines[1] and "focal length" not in lines[1]
    assert "b.pt: 1200 steps" in lines[2] and "8000 frames of 400 rooms (data seed 1, focal length x 0.80..1.25" \
        in lines[2]
    assert _first_stage(third) is first and _first_stage(first) is first


def test_a_stage_says_its_losses_and_where_it_ran() -> None:
    """The shipped recipe's stage: trained on a GPU with the scale-invariant and gradient terms, as its manifest says
    (a line that read '4 CPU threads' and only berHu for it was wrong)."""
    gpu = _manifest(7000, [120, 160], None)
    gpu["training"].update(silog_weight=0.5, gradient_weight=0.5)
    gpu["environment"] = {"threads": 4, "device": "NVIDIA H200"}
    (line,) = _optimisation_lines(gpu)
    assert "+ 0.5 x scale-invariant log loss + 0.5 x log-depth gradient matching + 0.5 x cross-entropy" in line
    assert line.endswith("0.10 h on one NVIDIA H200.")
    (cpu_line,) = _optimisation_lines(_manifest(100, [96, 128], None))
    assert cpu_line.endswith("on log depth + 0.5 x cross-entropy; 0.10 h on 2 CPU threads.")
