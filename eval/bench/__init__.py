"""Suites and runs: the method table, sequences, suites, one run and its folder, a suite's runs on an executor, the
regression gate and its calibration, throughput (see :mod:`eval` for the modules)."""
