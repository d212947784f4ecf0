"""Concepts the world (``sim_envs``), the agent (``cnnslam``) and the judge (``eval``) share, defined once.

A leaf: it imports none of the three packages, and all three may import it, so that the judge still never imports
the agent. What lives here is what both sides must agree on to the bit:

- :mod:`slamcommon.labels`: the semantic classes and the "no label" / "no depth" markers of ground truth;
- :mod:`slamcommon.se3`: the inverse and the relative pose of rigid transforms ``T_a_b`` (4x4, OpenCV camera axes);
- :mod:`slamcommon.depth_metrics`: the paper's correct depth (Sec. 4.1) and the usual depth accuracies;
- :mod:`slamcommon.semantic_metrics`: the confusion matrix, pixel accuracy and IoU of label maps;
- :mod:`slamcommon.strict_json`: strict JSON of records (NaN/inf as null, numpy values as Python ones);
- :mod:`slamcommon.config`: every method's configuration changed by dotted keys, values checked against their types
  (the one ``with_overrides``);
- :mod:`slamcommon.formats`: the file formats of the usual benchmarks (TUM, KITTI, ICL-NUIM, 7-Scenes) and the TUM
  tools' timestamp association, read by the world's folders and the judge;
- :mod:`slamcommon.errors`: the project's one exception root, :class:`~slamcommon.errors.ProjectError`, below which
  each package has its own base.
"""
