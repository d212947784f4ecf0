"""Inference speed of the depth network: ``python -m cnnslam.depthnet.bench`` prints warm ms per 320x240 frame.

The figure is the time of :meth:`DepthNetPredictor.predict` (network, softmax, eq. 5) on one image after warm-up
calls (the first calls set up kernels and are much slower), with torch limited to ``threads`` intra-op threads.
Speed does not depend on the weights' values: without shipped weights the default architecture is timed with
random weights, and the output says so.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import torch

from cnnslam.depthnet.model import DepthSemanticNet, ModelConfig, count_parameters
from cnnslam.depthnet.predict import DepthNetPredictor, load_predictor
from cnnslam.depthnet.weights_io import DEFAULT_WEIGHTS


@dataclass(frozen=True)
class BenchResult:
    """Warm inference times in milliseconds per frame of ``width`` x ``height`` on ``threads`` threads."""

    median_ms: float
    mean_ms: float
    min_ms: float
    p90_ms: float
    repeats: int
    width: int
    height: int
    threads: int
    parameters: int
    weights: str


def benchmark(
    predictor: DepthNetPredictor, width: int = 320, height: int = 240, warmup: int = 5, repeats: int = 30,
    weights_label: str = "",
) -> BenchResult:
    """Time ``predictor.predict`` on a fixed random image after ``warmup`` untimed calls."""
    rgb = np.random.default_rng(0).integers(0, 256, (height, width, 3), dtype=np.uint8)
    k = np.array([0.75 * width, 0.75 * width, width / 2 - 0.5, height / 2 - 0.5])
    for _ in range(warmup):
        predictor.predict(rgb, k)
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        predictor.predict(rgb, k)
        times.append((time.perf_counter() - t0) * 1000.0)
    t = np.array(times)
    return BenchResult(
        float(np.median(t)), float(t.mean()), float(t.min()), float(np.percentile(t, 90)), repeats, width, height,
        torch.get_num_threads(), count_parameters(predictor.model), weights_label,
    )


def main(argv: list[str] | None = None) -> int:
    """Command line: print the benchmark figure (and optionally write it as JSON)."""
    parser = argparse.ArgumentParser(prog="python -m cnnslam.depthnet.bench", description=__doc__.splitlines()[0])
    parser.add_argument("--weights", type=Path, default=None, help="weights file (default: the shipped ones)")
    parser.add_argument("--threads", type=int, default=2, help="torch intra-op threads (default 2)")
    parser.add_argument("--width", type=int, default=320)
    parser.add_argument("--height", type=int, default=240)
    parser.add_argument("--repeats", type=int, default=30)
    parser.add_argument("--json", type=Path, default=None, help="also write the result to this JSON file")
    args = parser.parse_args(argv)
    path = args.weights or DEFAULT_WEIGHTS
    if path.is_file():
        predictor = load_predictor(path, num_threads=args.threads)
        label = str(path)
    else:
        torch.manual_seed(0)
        predictor = DepthNetPredictor(DepthSemanticNet(ModelConfig()), 259.58, (320, 240), num_threads=args.threads)
        label = "random weights, default architecture (no weights file found)"
    res = benchmark(predictor, args.width, args.height, repeats=args.repeats, weights_label=label)
    print(
        f"depthnet inference {res.width}x{res.height}, {res.threads} threads, warm: median {res.median_ms:.1f} ms/frame"
        f" (mean {res.mean_ms:.1f}, min {res.min_ms:.1f}, p90 {res.p90_ms:.1f}; {res.repeats} runs;"
        f" {res.parameters / 1e6:.2f} M parameters; {label})"
    )
    if args.json is not None:
        args.json.write_text(json.dumps(asdict(res), indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
