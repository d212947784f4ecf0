"""The names under which an agent reports about itself, defined once for the agent and the judge.

An agent's ``step`` answers ``{T_WORLD_CAM: (4, 4) float64, TRACKED: 0|1}`` (the action of
:mod:`sim_envs.agent`); its ``finish`` extras hold at least ``{FRAMES: frames stepped, TRACKED_SHARE: share of them
tracked, 0..1}``. The judge scores the same share from the per-frame flags under the same name
(:data:`eval.metrics.catalogue.TRACKED_SHARE`), so the agent never imports the judge to spell it.
"""

from __future__ import annotations

T_WORLD_CAM = "T_world_cam"  # step(): the estimated camera-to-world pose, (4, 4) float64
TRACKED = "tracked"  # step(): 1 when the agent tracked this frame, 0 when it is lost
FRAMES = "frames"  # finish() extras: the frames the agent stepped
TRACKED_SHARE = "tracked_share"  # finish() extras: the share (0..1) of its frames the agent tracked
