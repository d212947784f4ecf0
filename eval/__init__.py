"""The judge: trajectory and depth metrics, tables, plots, benchmark suites and the regression gate.

Never imports ``cnnslam``: agents are named by ``"module:Class"`` strings, environments by Gymnasium id.
"""
