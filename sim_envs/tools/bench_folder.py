"""Real-folder reading benchmark: frames per second an RGB-D folder delivers to an agent that does nothing.

``python -m sim_envs.tools.bench_folder FOLDER [--frames N] [--prefetch K ...] [--size WxH | --size native]
[--reader rgb|frame] [--cold] [--digest]`` replays the first N frames of FOLDER through
:class:`sim_envs.env.ReplayEnv` (reset, then one step per frame with a fixed pose: the agent's cost is nil) and
prints, for each read-ahead depth K (0: frames read when asked, as before prefetching), the frames per second
delivered and milliseconds per frame, from ``reset`` to the last observation, and the process's CPU milliseconds
per frame (all threads) with the rate two idle cores could give at that cost at most (2 / CPU seconds per frame:
what "alone on 2 cores" can reach when other work shares the machine and the wall clock says little).

``--reader rgb`` (default) is what a monocular run reads (the RGB image alone: ``ground_truth="pose"``),
``--reader frame`` what a run with full ground truth reads (RGB, depth, labels). ``--cold`` first asks the kernel
to drop the folder's image files from the page cache (``posix_fadvise(POSIX_FADV_DONTNEED)``, per file: no
privileges needed, other files untouched), so each row reads them from disk; otherwise they are read as the page
cache holds them (warm after the first row). ``--digest`` also prints the SHA-256 of every delivered array (RGB,
timestamp, and the ground-truth pose and depth), so rows with different K can be compared byte for byte.
``--prepared DIR`` keeps the delivered RGB images under DIR (:mod:`sim_envs.folders.prepared`): the first row
converts and stores them, later rows and runs read them back (column ``kept``; ``--cold`` drops those files too).
Figures only: nothing is asserted.
"""

from __future__ import annotations

import argparse
import hashlib
import os
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from sim_envs.errors import SimEnvError
from sim_envs.folders.datasets import PREFETCH_AHEAD, PROCESSING_SIZE, RgbdFolder, check_size, detect_layout

READERS = ("rgb", "frame")


@dataclass(frozen=True)
class FolderReadFigures:
    """One timed replay: ``frames`` delivered in ``seconds`` (wall clock, reset to last observation) with read-ahead
    depth ``prefetch``; ``cold``: the folder's files were dropped from the page cache first; ``digest``: SHA-256
    (hex) of the delivered arrays, or None when not asked for; ``hits``: frames taken from a read ahead;
    ``cpu_seconds``: CPU time of the process (all its threads) over the same span; ``prepared_reads``: RGB images
    read back from the prepared images instead of converted."""

    prefetch: int
    frames: int
    seconds: float
    cpu_seconds: float
    cold: bool
    digest: str | None
    hits: int
    prepared_reads: int = 0

    @property
    def fps(self) -> float:
        """Frames delivered per second."""
        return self.frames / self.seconds if self.seconds > 0 else float("inf")

    @property
    def ms_per_frame(self) -> float:
        """Milliseconds per delivered frame."""
        return 1e3 * self.seconds / self.frames

    @property
    def cpu_ms_per_frame(self) -> float:
        """CPU milliseconds per delivered frame, all threads together."""
        return 1e3 * self.cpu_seconds / self.frames

    def fps_on(self, cores: int) -> float:
        """The frames per second ``cores`` idle cores could deliver at this CPU cost, at most (when the reading is
        spread over them): ``cores`` / CPU seconds per frame, capped by nothing else; a bound, not a measurement."""
        return cores * self.frames / self.cpu_seconds if self.cpu_seconds > 0 else float("inf")


def drop_from_page_cache(paths: Sequence[Path]) -> None:
    """Ask the kernel to drop each file's cached pages (``POSIX_FADV_DONTNEED``): the next read comes from disk.
    :class:`SimEnvError` where the platform has no ``posix_fadvise``."""
    if not hasattr(os, "posix_fadvise"):
        raise SimEnvError("--cold needs os.posix_fadvise (Linux); run without --cold on this platform")
    for path in paths:
        fd = os.open(path, os.O_RDONLY)
        try:
            os.posix_fadvise(fd, 0, 0, os.POSIX_FADV_DONTNEED)
        finally:
            os.close(fd)


def replay_folder(folder: str | Path, *, frames: int | None = None, prefetch: int = PREFETCH_AHEAD,
                  size: tuple[int, int] | None = PROCESSING_SIZE, reader: str = "rgb", cold: bool = False,
                  digest: bool = False, prepared: str | Path | None = None) -> FolderReadFigures:  # fmt: skip
    """Replay the first ``frames`` frames (None: all) of ``folder`` through :class:`~sim_envs.env.ReplayEnv` with a
    do-nothing agent, read ahead ``prefetch`` frames, delivered at ``size`` (None: the images' own) by ``reader``
    ("rgb": RGB alone, as a monocular run; "frame": full ground truth), the RGB images kept under ``prepared``
    when given (:mod:`sim_envs.folders.prepared`); see the module docstring."""
    from sim_envs.env import ReplayEnv
    from slamcommon.agent_keys import T_WORLD_CAM, TRACKED

    if reader not in READERS:
        raise SimEnvError(f"unknown reader {reader!r}; valid: {', '.join(READERS)}")
    if frames is not None and int(frames) < 1:
        raise SimEnvError(f"frames must be >= 1, got {frames}")
    source = RgbdFolder(folder, size=size, prefetch=prefetch, prepared=prepared)
    n = len(source) if frames is None else min(len(source), int(frames))
    if cold:
        store = source.prepared_images
        kept = [p for p in (store.path(i) for i in range(n)) if p.is_file()] if store is not None else []
        drop_from_page_cache([*source.rgb_paths[:n], *source.depth_paths[:n], *kept])
    env = ReplayEnv(source, ground_truth="full" if reader == "frame" else "pose", max_frames=n)
    hasher = hashlib.sha256() if digest else None
    action = {T_WORLD_CAM: np.eye(4), TRACKED: 1}
    try:
        start, cpu_start = time.perf_counter(), time.process_time()
        obs, info = env.reset()
        delivered, done = 1, False
        while True:
            if hasher is not None:
                for array in (obs["rgb"], obs["timestamp"], info["gt_T_world_cam"], info.get("gt_depth")):
                    if array is not None:
                        hasher.update(np.ascontiguousarray(array).tobytes())
            if done:
                break
            obs, _, terminated, truncated, info = env.step(action)
            done = terminated or truncated
            delivered += not done
        seconds, cpu_seconds = time.perf_counter() - start, time.process_time() - cpu_start
        hits = source.prefetch_hits
    finally:
        env.close()
    digest_hex = hasher.hexdigest() if hasher is not None else None
    kept = 0 if source.prepared_images is None else source.prepared_images.reads
    return FolderReadFigures(prefetch, delivered, seconds, cpu_seconds, cold, digest_hex, hits, kept)


def _size(text: str) -> tuple[int, int] | None:
    if text == "native":
        return None
    try:
        width, height = (int(v) for v in text.lower().split("x"))
    except ValueError as exc:
        raise argparse.ArgumentTypeError(f"size must be WIDTHxHEIGHT (e.g. 320x240) or native, got {text!r}") from exc
    return check_size((width, height))


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Command-line options of the benchmark."""
    parser.add_argument("folder", help="an RGB-D folder (TUM RGB-D, ICL-NUIM, 7-Scenes, RGB only)")
    parser.add_argument("--frames", type=int, default=None, help="frames replayed (default: all)")
    parser.add_argument("--prefetch", type=int, nargs="+", default=[0, PREFETCH_AHEAD],
                        help=f"frames read ahead, one row each (default: 0 {PREFETCH_AHEAD}; 0 = none)")
    parser.add_argument("--size", type=_size, default=PROCESSING_SIZE,
                        help="delivered size WIDTHxHEIGHT, or native for the images' own (default 320x240)")
    parser.add_argument("--reader", choices=READERS, default="rgb",
                        help="rgb: RGB alone, as a monocular run (default); frame: full ground truth (RGB + depth)")
    parser.add_argument("--cold", action="store_true",
                        help="drop the folder's image files from the page cache before each row")
    parser.add_argument("--prepared", default=None, metavar="DIR",
                        help="keep the delivered RGB images under DIR and read them back on later rows and runs")
    parser.add_argument("--digest", action="store_true", help="print the SHA-256 of every delivered array per row")


def check_arguments(args: argparse.Namespace) -> None:
    """:class:`SimEnvError` (one line) for a folder of no known layout, a frame count below 1 or a negative
    read-ahead depth, before anything is read."""
    if args.frames is not None and args.frames < 1:
        raise SimEnvError(f"--frames must be >= 1, got {args.frames}")
    bad = [k for k in args.prefetch if k < 0]
    if bad:
        raise SimEnvError(f"--prefetch depths must be >= 0 (0: no reading ahead), got {bad[0]}")
    detect_layout(Path(args.folder))


def run(args: argparse.Namespace) -> int:
    """Print one row per read-ahead depth; returns 0."""
    check_arguments(args)
    size = "native" if args.size is None else f"{args.size[0]}x{args.size[1]}"
    print(f"{args.folder}: reader {args.reader}, size {size}, {'cold' if args.cold else 'as cached'}, "
          f"{os.cpu_count()} CPUs")  # fmt: skip
    print(f"{'prefetch':>8} {'frames':>7} {'fps':>8} {'ms/frame':>9} {'cpu ms/frame':>13} {'2-core bound':>13} "
          f"{'hits':>6} {'kept':>6}" + ("  digest" if args.digest else ""))  # fmt: skip
    for k in args.prefetch:
        row = replay_folder(args.folder, frames=args.frames, prefetch=k, size=args.size, reader=args.reader,
                            cold=args.cold, digest=args.digest, prepared=args.prepared)  # fmt: skip
        tail = f"  {row.digest[:16]}" if row.digest else ""
        print(f"{k:>8} {row.frames:>7} {row.fps:>8.1f} {row.ms_per_frame:>9.2f} {row.cpu_ms_per_frame:>13.2f} "
              f"{row.fps_on(2):>9.1f} fps {row.hits:>6} {row.prepared_reads:>6}{tail}", flush=True)  # fmt: skip
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``python -m sim_envs.tools.bench_folder``; bad input: one line, exit status 2."""
    parser = argparse.ArgumentParser(prog="python -m sim_envs.tools.bench_folder", description=__doc__.splitlines()[0])
    add_arguments(parser)
    args = parser.parse_args(argv)
    try:
        return run(args)
    except SimEnvError as exc:
        print(f"bench_folder: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    raise SystemExit(main())
