"""``cnnslam bench [SUITE]``: run a benchmark suite and write its results (tables, plots, long-form CSV).

Suites (``--list`` prints them with their sequences and methods): ``table1`` (default), ``rotation``, ``ablation``,
``sweep``, ``depth_quality``, ``perf``, ``real`` (the folders of the local dataset list), ``transfer`` (the
simulated analogues against the real folders: do their rankings agree?), ``quick``; see
:mod:`eval.bench.suites`. ``--sequences`` takes sequence names, dataset-list names and paths of real RGB-D folders (TUM
RGB-D, ICL-NUIM, 7-Scenes, RGB-only; delivered at 320x240 unless ``--image-size``). Runs go to ``--out`` (one
folder per run, see :mod:`eval.bench.run`), results to ``--results`` (see :mod:`eval.reports.suite_reports`). A rerun
skips finished runs and retries failed ones; methods that cannot run here are skipped and reported.

Examples::

    cnnslam bench                                   # table1, whole sequences (the paper's) -> results/table1.md
    cnnslam bench table1 --frames 200 --results results/bench   # make bench: the bench length
    cnnslam bench rotation --jobs 2 --frames 90
    cnnslam bench table1 --methods CNN-SLAM oracle --sequences office0 living1 --frames 100
    cnnslam bench table1 --external MySLAM=out/myslam  # score a third-party system's output too
    cnnslam bench table1 --sequences ~/data/rgbd_dataset_freiburg1_desk   # a downloaded TUM sequence
    cnnslam bench real                              # every folder of datasets.toml (or $CNNSLAM_DATASETS)
    cnnslam bench transfer                          # sim rankings vs real ones, whole against whole and bench
                                                    # length against real windows -> results/transfer.md
    cnnslam bench transfer --frames all --camera clean,kinect   # whole sequences only, two simulated cameras
    cnnslam bench quick                             # the CI suite, compared with results/baselines/quick.json
    cnnslam bench quick --update-baseline           # after an intended change: rewrite the baseline
    cnnslam bench table1 --executor ray --address auto

Results: a suite run exactly as defined (any ``--runs``, ``--jobs``, executor) writes the committed tables under
``results/``; a subset or variant (``--sequences``, ``--methods``, ``--frames``, ``--seeds``, ``--external``,
``--method-file``) writes them under ``<out>/reports/<suite>-<digest of the selection>/`` instead, so it never
overwrites the committed results; ``--results DIR`` puts them where you say.

Exit status: 0 when every requested run finished (and the gate passed, where one runs); 1 when a run failed or
timed out, a requested method, external folder or listed dataset folder was skipped (``--allow-skips``: only
reported), or the gate
failed (the results are written all the same); 2 on bad arguments (one line, the valid names); 130 on Ctrl-C (the
runs finished before it are kept).
"""

from __future__ import annotations

import argparse
import hashlib
import shlex
import sys
from dataclasses import replace
from pathlib import Path

from eval.bench.executors import EXECUTORS, make_executor
from eval.bench.methods import (
    ALIGNMENTS,
    EXTERNAL_LAYOUT,
    MethodError,
    load_methods,
    merge_methods,
    parse_external,
    parse_setting,
    takes_config,
    with_settings,
)
from eval.bench.sequence_ref import dataset_list_file
from eval.bench.suites import SUITES, get_suite, sim_domain
from eval.errors import EvalError, SuiteError
from sim_envs.camera_effects import DEFAULT_CAMERA_EFFECTS
from slamcommon.errors import MetricError

DEFAULT_JOBS = 2  # runs in parallel: one per core of the 2-core machines the suites are sized for


def _names(values: list[str] | None) -> list[str] | None:
    """Names given as separate words and/or comma-separated."""
    if not values:
        return None
    return [n for v in values for n in v.split(",") if n]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.formatter_class = argparse.RawDescriptionHelpFormatter
    parser.epilog = f"external method folder layout (--external NAME=FOLDER):\n{EXTERNAL_LAYOUT}"
    select = parser.add_argument_group("what to run")
    select.add_argument("suite", nargs="?", default="table1", choices=list(SUITES), help="suite (default: table1)")
    select.add_argument("--sequences", nargs="+", metavar="NAME",
                        help="only these sequences (or others by name, dataset-list name, or the path of an RGB-D "
                             "folder: TUM RGB-D, ICL-NUIM, 7-Scenes, RGB-only)")  # fmt: skip
    select.add_argument("--methods", nargs="+", metavar="NAME", help="only these methods of the method table")
    select.add_argument("--frames", type=_frames, default=None,
                        help="first N frames of each sequence, or 'all' (default: the suite's)")  # fmt: skip
    select.add_argument("--lengths", type=_frames, nargs="+", default=None, metavar="N",
                        help="the lengths suite's lengths: numbers of frames and/or 'all' (default: 200 400 800 "
                             "all)")  # fmt: skip
    select.add_argument("--runs", type=int, default=None, metavar="N",
                        help="runs per cell, seeds 0..N-1 (default: 3); eval/methods.toml says what a seed changes")
    select.add_argument("--seeds", nargs="+", type=int, metavar="N", help="these seeds instead of --runs")
    select.add_argument("--list", action="store_true", help="list the suites and the method table, run nothing")
    images = parser.add_argument_group("the sequences' images")
    images.add_argument("--camera", default=None, metavar="PRESET|FILE",
                        help="simulated sequences: what the camera does to the images, kinect (a hand-held RGB-D "
                             "camera, default), clean (the renderer's bytes) or hard (sim_envs/camera_effects.py; "
                             "a name with @PRESET in --sequences picks one sequence's camera; "
                             "transfer: the simulated domains, comma-separated presets, each maybe with +lit and/or "
                             "+rich (clean,kinect,kinect+lit,kinect+rich), default the presets); folder "
                             "sequences: their calibration, a preset (tum_fr1, tum_fr2, tum_fr3, icl, 7scenes, ...) or "
                             "a camera file (TOML/YAML: fx fy cx cy [width height] [k1 k2 p1 p2 k3]); default: the "
                             "folder's "
                             "camera.toml, side file, or its name (freiburg1/2/3)")  # fmt: skip
    images.add_argument("--image-size", default=None, metavar="WxH",
                        help="resolution the folder sequences are delivered at (default 320x240, the paper's; "
                             "'native': the images' own)")  # fmt: skip
    images.add_argument("--undistort", choices=["crop", "full", "none"], default=None,
                        help="how a folder sequence's distorted lens is undistorted: crop (to what the lens saw, the "
                             "default), full (the whole frame with K, black border), none (the distorted images as "
                             "they are); a choice other than crop runs as <name>~<choice>")  # fmt: skip
    images.add_argument("--motion", action="append", default=[], type=Path, metavar="TUM_FILE",
                        help="transfer: a recorded camera motion (TUM trajectory file, e.g. a TUM RGB-D ground truth) "
                             "replayed in the simulated rooms as a simulated domain of its own (repeatable)")
    images.add_argument("--renderer", choices=("mujoco", "pyrender"), default="mujoco", help="renderer backend")
    images.add_argument("--no-frame-cache", action="store_true",
                        help="render every run's frames anew (default: a simulated sequence is rendered once and its "
                             "frames read back by the suite's other runs from <out>/.frames/: the same bytes)")
    methods = parser.add_argument_group("the methods")
    methods.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                         help="override one configuration field of every chosen agent that takes one (repeatable; "
                              "e.g. refinement.enabled=false); the runs' fingerprints carry it")  # fmt: skip
    methods.add_argument("--method-file", type=Path, default=None,
                         help="a method table (TOML, shaped like eval/methods.toml) added to the default")  # fmt: skip
    methods.add_argument("--override", action="store_true",
                         help="let --method-file redefine a built-in method of the same name")
    methods.add_argument("--external", action="append", default=[], metavar="NAME=FOLDER",
                         help="score a third-party system's output in FOLDER as method NAME (repeatable)")  # fmt: skip
    methods.add_argument("--no-check", action="store_true",
                         help="check only that each method's agent imports (not that it builds and steps)")  # fmt: skip
    running = parser.add_argument_group("how runs are run")
    running.add_argument("--jobs", type=int, default=DEFAULT_JOBS, help=f"runs in parallel (default: {DEFAULT_JOBS})")
    running.add_argument("--executor", choices=EXECUTORS, default="local",
                         help="local process pool (spawn, default), serial (in this process) or ray")  # fmt: skip
    running.add_argument("--address", default=None, help="Ray cluster address (auto, ray://host:10001, local)")
    running.add_argument("--reuse-workers", action="store_true",
                         help="local executor: run several runs per worker process (faster start; a run's last digits "
                              "may then depend on what its worker ran before)")  # fmt: skip
    running.add_argument("--timeout", type=float, default=None, metavar="S",
                         help="stop a run after S seconds of wall time and record it as failed (timed out)")
    running.add_argument("--rerun", action="store_true", help="run every run again, even finished ones")
    running.add_argument("--report-only", action="store_true",
                         help="run nothing: write the tables from the finished runs in --out, whatever revision made "
                              "them (each run records its revision)")  # fmt: skip
    running.add_argument("--out", type=Path, default=Path("runs"), help="per-run artifacts (default: runs/)")
    results = parser.add_argument_group("results")
    results.add_argument("--results", type=Path, default=None,
                         help="tables and plots (default: results/ for a suite as defined, else "
                              "<out>/reports/<suite>-<selection>/)")  # fmt: skip
    results.add_argument("--align", choices=ALIGNMENTS, default=None,
                         help="alignment of the headline ATE (default: the suite's, se3 as in the paper; a "
                              "method's own align wins); every run records ate_se3_rmse and ate_sim3_rmse")  # fmt: skip
    results.add_argument("--no-plots", action="store_true", help="no per-run plots (faster)")
    results.add_argument("--no-progress", action="store_true", help="no progress bars")
    results.add_argument("--allow-skips", action="store_true",
                         help="exit 0 even when a requested method or external folder was skipped")
    gate = parser.add_argument_group("the regression gate")
    gate.add_argument("--baseline", type=Path, default=None,
                      help="compare the suite's metrics with this baseline (default for quick: "
                           "results/baselines/quick.json)")  # fmt: skip
    gate.add_argument("--update-baseline", action="store_true",
                      help="write the suite's gated figures as its baseline (keeping its calibrated tolerances); "
                           "perf: the median frames per machine unit of 3 slam probes, results/baselines/perf.json")
    gate.add_argument("--calibrate", action="store_true",
                      help="run the suite under the perturbation matrix (eval/bench/calibrate.py: thread counts, "
                           "oneDNN off, the network's last bits perturbed, an older instruction set), record this "
                           "machine's figures in <baseline dir>/machines/<suite>/ and write the baseline with "
                           "tolerances from the spread measured over the matrix and the other machines' records "
                           "of the same runs")  # fmt: skip
    gate.add_argument("--no-gate", action="store_true", help="do not compare with the baseline")


def _command(args: argparse.Namespace) -> str:
    """The command line that reproduces the run (the options that shape the results), for the reports."""
    words = ["cnnslam", "bench", args.suite]
    renderer = None if args.renderer == "mujoco" else args.renderer
    for flag, value in (("--frames", args.frames), ("--runs", args.runs), ("--renderer", renderer),
                        ("--align", args.align), ("--camera", args.camera), ("--undistort", args.undistort),
                        ("--image-size", args.image_size)):  # fmt: skip
        if value is not None:
            words += [flag, str(value)]
    for flag, values in (("--sequences", _names(args.sequences)), ("--methods", _names(args.methods)),
                         ("--seeds", args.seeds), ("--lengths", getattr(args, "lengths", None))):  # fmt: skip
        if values:
            words += [flag, *map(str, values)]
    for text in args.external:
        words += ["--external", text]
    for path in getattr(args, "motion", []):
        words += ["--motion", str(path)]
    if args.method_file is not None:
        words += ["--method-file", str(args.method_file)]
    return " ".join(shlex.quote(w) for w in words)


def _frames(text: str) -> int | str:
    """``--frames``: a number of frames, or ``all`` (whole sequences)."""
    if text == "all":
        return text
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a number of frames or 'all', got {text!r}") from None


def _is_sim_domain(text: str) -> bool:
    """True when ``text`` names a simulated domain of the transfer suite (:func:`eval.bench.suites.sim_domain`)."""
    try:
        sim_domain(text)
    except SuiteError:
        return False
    return True


def _image_size(text: str | None):
    """``--image-size``: ``WxH`` -> (W, H), ``native``, or None when not given."""
    if text is None or text == "native":
        return text
    try:
        width, height = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise SuiteError(f"--image-size must be WIDTHxHEIGHT (e.g. 320x240) or native, got {text!r}") from None
    return width, height


def _list(methods: dict) -> str:
    lines = ["suites:"]
    for suite in SUITES.values():
        lines.append(f"  {suite.name:<9} {suite.description}")
        if suite.kind == "runs":
            if suite.real_folders:
                try:
                    suite = get_suite(suite.name)
                except SuiteError as exc:
                    lines.append(f"            {exc}")
            frames = "all" if suite.frames is None else suite.frames
            lines.append(f"            frames {frames}; sequences: {', '.join(s.name for s in suite.sequences)}")
            if suite.skipped:
                lines.append(f"            missing here: {', '.join(name for name, _ in suite.skipped)}")
            lines.append(f"            methods: {', '.join(suite.methods)}")
    lines.append("methods:")
    for m in methods.values():
        target = m.entry_point or m.folder
        lines.append(f"  {m.name:<17} {target}  {dict(m.agent_kwargs())}  [{', '.join(m.metrics)}]")
    return "\n".join(lines)


def results_folder(args: argparse.Namespace, suite, command: str, as_defined: bool = True) -> Path:
    """Where the suite's tables go: ``--results``; else ``results/`` for the suite as defined (``as_defined``: False
    for a variant the suite object does not show, e.g. other transfer lengths); else a folder named after the
    selection under ``<out>/reports/`` (a subset never overwrites the committed results)."""
    if args.results is not None:
        return args.results
    if as_defined and suite.is_default and not args.external and args.method_file is None:
        return Path("results")
    digest = hashlib.sha256(command.encode()).hexdigest()[:8]
    return args.out / "reports" / f"{suite.name}-{digest}"


def run(args: argparse.Namespace) -> int:
    command = _command(args)
    try:
        methods = load_methods()
        if args.method_file is not None:
            methods = merge_methods(methods, load_methods(args.method_file), str(args.method_file), args.override)
        externals = [parse_external(text) for text in args.external]
        methods = merge_methods(methods, {m.name: m for m in externals}, "--external", args.override)
        if args.list:
            print(_list(methods))
            return 0
        suite = get_suite(args.suite)
        if args.motion and suite.kind != "transfer":
            raise SuiteError("--motion applies to the transfer suite (a recorded motion as a simulated domain)")
        if args.lengths is not None and suite.kind not in ("lengths", "transfer"):
            raise SuiteError("--lengths applies to the lengths and transfer suites; other suites take --frames")
        if args.lengths is not None and args.frames is not None:
            raise SuiteError("give --lengths or --frames, not both")
        if suite.kind == "perf":
            from eval.bench.perf import run_perf

            results = args.results or Path("results")
            frames = None if args.frames == "all" else args.frames
            report = run_perf(results, frames=frames, progress=not args.no_progress,
                              update_speed_baseline=args.update_baseline)
            print(f"wrote {results / 'perf.md'} and {results / 'perf.json'}")
            gate = report.speed_gate or {}
            if gate.get("error"):
                print(f"speed gate not judged: {gate['error']}")
            else:
                print("speed gate: " + ("; ".join(gate["failures"]) if gate["failures"] else "passed"))
            return 0 if report.ok else 1
        chosen = _names(args.methods) or list(suite.methods)
        unknown = [name for name in chosen if name not in methods]
        if unknown:
            raise MethodError(f"unknown method(s) {', '.join(unknown)}; valid methods: {', '.join(methods)}")
        chosen += [m.name for m in externals if m.name not in chosen]
        if args.set:  # into every chosen agent that takes a configuration; its runs' fingerprints carry them
            settings = [parse_setting(text) for text in args.set]
            configurable = [name for name in chosen if takes_config(methods[name])]
            if not configurable:
                raise MethodError(f"--set: none of the chosen methods ({', '.join(chosen)}) takes a configuration")
            methods = {**methods, **{name: with_settings(methods[name], settings) for name in configurable}}
            print(f"--set {' '.join(args.set)}: applied to {', '.join(configurable)} (cnnslam config METHOD --set ... "
                  "prints the result)")
        camera, presets = args.camera, None
        if suite.kind == "transfer" and camera is not None and all(_is_sim_domain(c) for c in camera.split(",")):
            camera, presets = None, tuple(args.camera.split(","))  # the simulated part's cameras, e.g. clean,kinect
        suite = suite.select(_names(args.sequences), chosen, args.frames, args.seeds, args.runs,
                             camera=camera, size=_image_size(args.image_size), undistort=args.undistort)  # fmt: skip
        if args.align is not None:
            suite = replace(suite, alignment=args.align)
        if args.timeout is not None and not args.timeout > 0:
            raise MethodError(f"--timeout must be a number of seconds > 0, got {args.timeout}")
        options = {"timeout_s": args.timeout} if args.timeout is not None else {}
        # the fork server imports the agents' modules once; each run still gets a fresh worker forked from it
        preload = [methods[m].entry_point.partition(":")[0] for m in chosen if methods[m].entry_point]
        executor = make_executor(args.executor, args.jobs, args.address, fresh_workers=not args.reuse_workers,
                                 preload=preload, **options)  # fmt: skip
    except (EvalError, MetricError) as exc:
        print(f"cnnslam bench: error: {exc}", file=sys.stderr)
        return 2
    from eval.reports.suite_reports import write_report

    if suite.kind == "transfer":
        return _transfer(args, suite, methods, executor, command, presets)
    if suite.kind == "lengths":
        return _lengths(args, suite, methods, executor, command)
    if suite.kind == "preprocessing":
        return _preprocessing(args, suite, methods, executor, command)
    if not suite.sequences:
        for name, reason in suite.skipped:
            print(f"  skipped sequence {name}: {reason}")
        print(f"cnnslam bench: suite {suite.name} has no sequence to run here ({len(suite.skipped)} skipped; the "
              f"dataset list is {dataset_list_file()})", file=sys.stderr)  # fmt: skip
        return 0 if args.allow_skips and suite.skipped else 1
    if args.calibrate:
        return _calibrate(args, suite, methods, command)
    try:
        result = _run_suite(args, suite, methods, executor)
    except KeyboardInterrupt:
        print(f"cnnslam bench: interrupted; finished runs are kept under {args.out}/{suite.name}/ (rerun the same "
              "command to resume)", file=sys.stderr)  # fmt: skip
        return 130
    paths = write_report(result, results_folder(args, suite, command), command)
    counts = result.counts()
    print(
        f"{suite.name}: {len(result.specs)} runs ({counts.get('done', 0)} run now, {counts.get('cached', 0)} reused, "
        f"{counts.get('failed', 0)} failed); {len(result.skipped_methods)} method(s) skipped"
    )
    for name, reason in result.skipped_methods.items():
        print(f"  skipped {name}: {reason}")
    for outcome in result.failed:
        print(f"  FAILED {outcome.key}: {outcome.error}")
    print("wrote " + ", ".join(str(p) for p in paths))
    for name, reason in suite.skipped:
        print(f"  skipped sequence {name}: {reason}")
    status = 1 if result.failed else 0
    if result.skipped_methods and not args.allow_skips:
        print(f"cnnslam bench: {len(result.skipped_methods)} requested method(s) skipped ("
              f"{', '.join(result.skipped_methods)}): exit status 1 (--allow-skips to accept)", file=sys.stderr)
        status = 1
    if suite.skipped and not args.allow_skips:
        print(f"cnnslam bench: {len(suite.skipped)} listed sequence(s) skipped ("
              f"{', '.join(name for name, _ in suite.skipped)}): exit status 1 (--allow-skips to accept)",
              file=sys.stderr)  # fmt: skip
        status = 1
    return max(status, _gate(args, result))


def _run_suite(args: argparse.Namespace, suite, methods: dict, executor):
    """``run_suite`` with the command line's run options (renderer, plots, progress, check, rerun, report-only)."""
    from eval.bench.runner import run_suite

    return run_suite(suite, methods, args.out, executor=executor, renderer=args.renderer,
                     plots=not args.no_plots, progress=not args.no_progress, check=not args.no_check,
                     rerun=args.rerun, report_only=args.report_only,
                     frame_cache=not args.no_frame_cache)  # fmt: skip


def _transfer(args: argparse.Namespace, suite, methods: dict, executor, command: str,
              presets: tuple[str, ...] | None = None) -> int:
    """The transfer suite: each part (:func:`eval.bench.suites.transfer_parts`; ``presets``: the simulated part's camera
    presets, default the default camera) run as its own suite (so its runs are shared with ``make bench``,
    ``cnnslam bench table1`` and ``cnnslam bench real``), then ``transfer.{md,csv,png}``."""
    from eval.bench.suites import transfer_parts
    from eval.reports.transfer_report import report_transfer

    lengths = None if args.lengths is None else tuple(None if n == "all" else n for n in args.lengths)
    plan = [p for p in transfer_parts(suite, presets or (DEFAULT_CAMERA_EFFECTS,), lengths, motions=args.motion)
            if p.suite.sequences]  # fmt: skip
    try:
        done, status = _run_parts(args, [(", ".join(dict.fromkeys(d for _, d in p.domains)), p.suite) for p in plan],
                                  methods, executor)  # fmt: skip
    except KeyboardInterrupt:
        print(f"cnnslam bench: interrupted; finished runs are kept under {args.out}/ (rerun the same command to "
              "resume)", file=sys.stderr)  # fmt: skip
        return 130
    parts = [(p, run) for p, (_, run) in zip(plan, done, strict=True)]
    as_defined = lengths is None and presets is None and not args.motion  # else a variant: never over results/
    paths = report_transfer(parts, results_folder(args, suite, command, as_defined), command)
    print("wrote " + ", ".join(str(p) for p in paths))
    for name, reason in suite.skipped:
        print(f"  skipped sequence {name}: {reason}")
    if not suite.sequences or (suite.skipped and not args.allow_skips):
        print(f"cnnslam bench: {len(suite.skipped)} listed real sequence(s) skipped, {len(suite.sequences)} run: "
              f"exit status 1 (--allow-skips to accept; the dataset list is {dataset_list_file()})",
              file=sys.stderr)  # fmt: skip
        status = 1
    return status


def _run_parts(args: argparse.Namespace, parts: list, methods: dict, executor) -> tuple[list, int]:
    """Run each ``(label, suite)`` of a suite made of parts as its own suite (its runs that suite's own); returns
    the ``(label, SuiteRun)`` pairs and the exit status (1 when a run failed, or a method was skipped without
    ``--allow-skips``). Ctrl-C propagates; the runs finished before it are stored."""
    done, status = [], 0
    for label, part in parts:
        print(f"{args.suite}: {label}: suite {part.name}, {len(part.sequences)} sequence(s), "
              f"{'whole sequences' if part.frames is None else f'{part.frames} frames'}")
        result = _run_suite(args, part, methods, executor)
        done.append((label, result))
        for outcome in result.failed:
            print(f"  FAILED {outcome.key}: {outcome.error}")
        status = max(status, 1 if result.failed or (result.skipped_methods and not args.allow_skips) else 0)
    return done, status


def _lengths(args: argparse.Namespace, suite, methods: dict, executor, command: str) -> int:
    """The length sweep: the table1 suite at each length (:func:`eval.bench.suites.length_parts`; ``--lengths``), each
    run as its own suite (its runs are ``make bench``'s and ``cnnslam bench table1``'s), then
    ``lengths.{md,csv,png}``."""
    from eval.bench.suites import SWEEP_LENGTHS, length_parts
    from eval.reports.lengths_report import report_lengths

    lengths = SWEEP_LENGTHS if args.lengths is None else tuple(None if n == "all" else n for n in args.lengths)
    try:
        parts, status = _run_parts(args, length_parts(suite, lengths), methods, executor)
    except KeyboardInterrupt:
        print(f"cnnslam bench: interrupted; finished runs are kept under {args.out}/ (rerun the same command to "
              "resume)", file=sys.stderr)  # fmt: skip
        return 130
    paths = report_lengths(parts, results_folder(args, suite, command, set(lengths) == set(SWEEP_LENGTHS)), command)
    print("wrote " + ", ".join(str(p) for p in paths))
    return status


def _preprocessing(args: argparse.Namespace, suite, methods: dict, executor, command: str) -> int:
    """The preprocessing suite: the real folders under the loader's defaults and each choice that applies
    (:func:`eval.bench.suites.preprocessing_parts`), each run as the ``real`` suite, then ``preprocessing.{md,csv}``."""
    from eval.bench.suites import preprocessing_parts
    from eval.reports.sensitivity_report import report_preprocessing

    triples = preprocessing_parts(suite)
    try:
        parts, status = _run_parts(args, [(choice, part) for choice, part, _ in triples], methods, executor)
    except KeyboardInterrupt:
        print(f"cnnslam bench: interrupted; finished runs are kept under {args.out}/ (rerun the same command to "
              "resume)", file=sys.stderr)  # fmt: skip
        return 130
    domains = {choice: d for choice, _, d in triples}
    paths = report_preprocessing([(c, run, domains[c]) for c, run in parts], results_folder(args, suite, command),
                                 command)  # fmt: skip
    print("wrote " + ", ".join(str(p) for p in paths))
    if not suite.sequences or (suite.skipped and not args.allow_skips):
        print(f"cnnslam bench: {len(suite.skipped)} listed real sequence(s) skipped, {len(suite.sequences)} run "
              f"(the dataset list is {dataset_list_file()})", file=sys.stderr)  # fmt: skip
        status = 1
    return status


def _calibrate(args: argparse.Namespace, suite, methods: dict, command: str) -> int:
    """``--calibrate``: the suite under every configuration of the matrix, then its baseline (see eval.bench.calibrate)
    and the suite's report from the reference configuration's runs."""
    from eval.bench.calibrate import (
        MATRIX,
        calibrated_baseline,
        load_machine_records,
        machine_record,
        measure,
        run_fingerprints,
        save_machine_record,
    )
    from eval.bench.regress import save_baseline
    from eval.bench.runner import git_revision
    from eval.reports.suite_reports import write_report

    if args.executor != "local" or args.jobs != DEFAULT_JOBS or args.reuse_workers:
        print("cnnslam bench: error: --calibrate runs its matrix's own local pools (2 runs at a time, then 1 with 2 "
              "threads; eval/bench/calibrate.py): --executor, --jobs and --reuse-workers do not apply", file=sys.stderr)
        return 2
    failed: list[str] = []
    runs: dict[str, object] = {}

    def note(config, run) -> None:
        print(f"{config.name}: {len(run.specs)} runs, {len(run.failed)} failed ({config.description})")
        failed.extend(f"{config.name}: {o.key}: {o.error}" for o in run.failed)
        runs[config.name] = run

    try:
        records = measure(suite, methods, args.out, progress=not args.no_progress, on_config=note,
                          renderer=args.renderer, timeout_s=args.timeout)
    except KeyboardInterrupt:
        print("cnnslam bench: calibration interrupted; finished runs are kept", file=sys.stderr)
        return 130
    if failed:
        print("not writing a baseline: runs failed:\n  " + "\n  ".join(failed), file=sys.stderr)
        return 1
    path = Path(args.baseline or suite.baseline_path)
    reference = records[MATRIX[0].name]
    own = save_machine_record(machine_record(suite, reference, git_revision() or ""),
                              path.parent / "machines" / suite.name)
    print(f"wrote {own}: this machine's reference figures")
    machines, left_out = load_machine_records(own.parent, suite.name, run_fingerprints(reference), exclude=own.name)
    for why in left_out:
        print(f"left out of the calibration: {why}")
    baseline = calibrated_baseline(suite, records, _baseline_description(suite), MATRIX, machines=machines)
    save_baseline(baseline, path)
    paths = write_report(runs[MATRIX[0].name], results_folder(args, suite, command), command)
    print("wrote " + ", ".join(str(p) for p in paths) + f" (the {MATRIX[0].name} configuration's runs)")
    holdout = baseline.calibration["holdout"]
    print(f"wrote {path}: {len(baseline.metrics)} gated figures, {len(baseline.calibrated)} calibrated; held-out "
          f"false alarms {holdout['alarms']} of {holdout['comparisons']} comparisons "
          f"({holdout['runs_with_alarm']} of {holdout['held_out']} held-out configurations would fail); other "
          f"machines folded in: {', '.join(sorted(machines)) or 'none'}")
    return 0


def _baseline_description(suite) -> str:
    frames = "all" if suite.frames is None else suite.frames
    return (f"cnnslam bench {suite.name}: {frames} frames, {len(suite.seeds)} runs per cell, sequences "
            f"{', '.join(s.name for s in suite.sequences)}; methods {', '.join(suite.methods)}")  # fmt: skip


def _gate(args: argparse.Namespace, result) -> int:
    """Update or compare with the suite's baseline; the exit status of the gate (0 pass, 1 fail)."""

    from eval.bench.regress import compare, format_report, gate_metrics, load_baseline, update_baseline

    suite = result.suite
    path = args.baseline or suite.baseline_path
    metrics = gate_metrics(result.records)
    if args.update_baseline:
        if result.failed or result.skipped_methods:
            print(f"not updating {path}: {len(result.failed)} run(s) failed, {len(result.skipped_methods)} method(s) "
                  "skipped", file=sys.stderr)  # fmt: skip
            return 1
        new = update_baseline(path, metrics, description=_baseline_description(suite))
        print(f"updated {path}: {len(metrics)} gated figures ({len(new.calibrated)} with calibrated tolerances; "
              f"recalibrate with --calibrate after a change of the methods' spread)")
        return 0
    if args.no_gate or (args.baseline is None and not suite.gated):
        return 0
    if not path.exists():
        print(f"no baseline at {path}; create it with: cnnslam bench {suite.name} --update-baseline")
        return 0 if args.baseline is None else 1
    report = compare(load_baseline(path), metrics)
    print(format_report(report, only_changes=True))
    return 0 if report.passed else 1
