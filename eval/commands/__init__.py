"""The judge's command lines, registered in :mod:`cnnslam.cli` (``cnnslam bench``, ``eval``, ``regress``,
``config``, ``export``, ``generate``, ``reference``): arguments in, a library call, a summary out. The only users
of argparse and print in :mod:`eval`."""
