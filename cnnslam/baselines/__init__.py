"""Baselines of the paper's Table 1 that are not configurations of CNN-SLAM itself, as ``sim_envs`` agents.

- ``"cnnslam.baselines.orb:OrbSlamAgent"``: ORB-SLAM [20], feature-based monocular SLAM with OpenCV (ORB features,
  two-view initialisation, PnP tracking, local bundle adjustment); sparse key-frame depth, no absolute scale.
- ``"cnnslam.baselines.laina:LainaAgent"``: Laina et al. [16], the CNN depth of every frame fed to point-based
  RGB-D fusion with ICP tracking, without refinement.
- ``"cnnslam.baselines.remode:RemodeAgent"``: REMODE [23], per-pixel probabilistic dense depth on the LSD-BS
  trajectory; scored on depth only (its ATE is LSD-BS's: '-' in the table).

Each is built on :class:`cnnslam.baselines.base.BaselineAgent`, the shell of the agent contract (``reset``'s checks,
``step``'s record of timestamps, poses and tracked flags, ``finish``'s guard); a new baseline is one module with a
subclass plus one ``[methods."NAME"]`` table in ``eval/methods.toml`` (``table1 = true``: a Table-1 method;
``warmup``: compiled at install by :mod:`cnnslam.tools.warmup`). Their ``"module:Class"`` names are the ones above.

LSD and LSD-BS are presets of ``"cnnslam.agent:CnnSlamAgent"`` / ``"cnnslam.agent:GroundTruthAidedAgent"``
(``preset="lsd"``, ``preset="lsd_bs"``), not separate code.
"""
