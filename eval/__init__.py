"""The judge: trajectory and depth metrics, tables, plots, benchmark suites and the regression gate.

Never imports ``cnnslam``: agents are named by ``"module:Class"`` strings, environments by Gymnasium id.

- :mod:`eval.trajectory` (poses, SE(3) helpers), :mod:`eval.association` (TUM greedy / evo nearest),
  :mod:`slamcommon.alignment` (SE(3), Sim(3), origin, none; rotation-only fallback), :mod:`eval.metrics` (ATE, RPE,
  rotation and scale error, tracked share, length);
- :mod:`slamcommon.depth_metrics` (the paper's percentage of correct depth, density, AbsRel, RMSE, delta < 1.25),
  :mod:`slamcommon.semantic_metrics` (pixel accuracy, IoU), :mod:`slamcommon.reconstruction_metrics` and
  :mod:`eval.map_metrics` (the agent's global model against the scene); the metric primitives and the alignment
  live in :mod:`slamcommon`, the leaf that the agent's development tools share with the judge;
- :mod:`eval.results` (score an episode, run records, long-form frames), :mod:`eval.tables` (Table 1),
  :mod:`eval.paper_table1` (the paper's numbers), :mod:`eval.plots`, :mod:`eval.regress` (the gate);
- command lines: ``cnnslam eval`` (:mod:`eval.cli_eval`), ``cnnslam regress``, ``cnnslam export``;
  ``python -m eval.bench_metrics`` times the metrics on 100k poses.

File formats (TUM, KITTI) and dataset folders live in ``sim_envs.formats`` / ``sim_envs.datasets``: the world reads
and writes them and must not import the judge. :mod:`eval.tum_reader` reads TUM trajectories for the judge with the
same results and errors, faster and without importing the world (``cnnslam eval`` loads numpy and the judge only).
"""
