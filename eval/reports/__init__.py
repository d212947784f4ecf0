"""What is made of runs: tables, plots, each suite's report, and the analyses of the suites made of several parts
(transfer, lengths, preprocessing) with their reports (see :mod:`eval` for the modules)."""
