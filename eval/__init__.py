"""The judge: it scores what an agent hands back against the world's ground truth. Never imports ``cnnslam``:
agents are named by ``"module:Class"`` strings, environments by Gymnasium id.

Its parts, one subpackage each (as ``cnnslam/`` has one module per stage of the paper), in layers: each imports
only the parts below it, commands > bench > reports > metrics > :mod:`eval.errors`, with no circle (pyproject.toml's
import-linter contracts, checked by ``lint-imports`` in ``make lint``):

- :mod:`eval.metrics`: scoring one trajectory or episode: poses and their files (:mod:`eval.metrics.trajectory`),
  timestamp association (:mod:`eval.metrics.association`), ATE / RPE / rotation and
  scale error (:mod:`eval.metrics.trajectory_metrics`), the agent's global model (:mod:`eval.metrics.map_metrics`),
  a scored episode as a run record (:mod:`eval.metrics.results`), a run folder's files and a run's trajectory scored
  as its record scores it (:mod:`eval.metrics.runs`), a second reference for real folders
  (:mod:`eval.metrics.sfm_reference`); the metric primitives and the alignment live in :mod:`slamcommon`;
- :mod:`eval.bench`: suites and runs: the method table (:mod:`eval.bench.methods`, data in ``eval/methods.toml``),
  sequences (:mod:`eval.bench.sequence_ref`), suites (:mod:`eval.bench.suites`), one run
  (:mod:`eval.bench.run`, :mod:`eval.bench.run_store`), a suite's runs (:mod:`eval.bench.runner`) on an executor
  (:mod:`eval.bench.executors`), the regression gate and its calibration (:mod:`eval.bench.regress`,
  :mod:`eval.bench.calibrate`), throughput (:mod:`eval.bench.perf`), and the benchmark as one call: its options and
  checks (:mod:`eval.bench.plan`), then the runs, their reports and the gate (:mod:`eval.bench.benchmark`);
- :mod:`eval.reports`: what is made of runs: tables (:mod:`eval.reports.tables`, the paper's numbers in
  :mod:`eval.reports.paper_table1`), plots (:mod:`eval.reports.plots`, the one module that draws), each suite's report
  (:mod:`eval.reports.suite_reports`), and the analyses of the suites made of several parts (transfer, lengths,
  preprocessing) with their reports; what they read of the benchmark's objects is :mod:`eval.reports.inputs`
  (protocols), so that they import nothing of :mod:`eval.bench`;
- :mod:`eval.commands`: the command lines (``cnnslam bench``, ``eval``, ``regress``, ``config``, ``export``,
  ``generate``, ``reference``, ``results``; ``results make`` remakes stale results with :mod:`eval.commands.remake`),
  the only users of argparse and print.

File formats (TUM, KITTI, ICL-NUIM, 7-Scenes) and the TUM tools' association live once in :mod:`slamcommon.formats`,
which the world (``sim_envs.folders.formats``, ``sim_envs.folders.datasets``: dataset folders) and the judge both read,
so that
``cnnslam eval`` loads numpy and the judge only, not the world.
"""
