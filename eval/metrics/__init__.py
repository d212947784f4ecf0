"""Scoring one trajectory or one episode: poses, association, ATE / RPE / rotation and scale error, the global
model's accuracy, and the run record a scored episode becomes (see :mod:`eval` for the modules)."""
