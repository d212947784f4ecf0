"""The simulated world: procedural indoor scenes, offscreen renderers, camera trajectories, Gymnasium environments.

Knows nothing of SLAM. Conventions: camera x right, y down, z forward (OpenCV); poses ``T_world_cam`` 4x4;
depth metric planar z in metres (0 = no surface); images H x W.

Importing the package registers its Gymnasium environments (lazily, by ``"module:Class"`` strings, so nothing heavy
is imported until an environment is made):

- ``sim_envs/Scene-v0``: a sequence built from arguments (style, seed, trajectory kind and parameters, renderer,
  camera, n_frames), :class:`sim_envs.env.SceneEnv`;
- ``sim_envs/Replay-v0``: replays a given frame source or an RGB-D folder (TUM, ICL-NUIM, 7-Scenes, RGB-only),
  :class:`sim_envs.env.ReplayEnv`;
- ``sim_envs/<name>-v0`` for every named sequence of :mod:`sim_envs.sequences` (``sim_envs/office0-v0``...),
  :class:`sim_envs.env.SlamEnv`.
"""

from __future__ import annotations


def _register_envs() -> list[str]:
    """Register the environments with Gymnasium (once per process); return their ids."""
    import gymnasium

    from sim_envs.sequences import gym_id, registered_names

    ids = []
    entries: list[tuple[str, str, dict]] = [
        ("sim_envs/Scene-v0", "sim_envs.env:SceneEnv", {}),
        ("sim_envs/Replay-v0", "sim_envs.env:ReplayEnv", {}),
    ]
    entries += [(gym_id(name), "sim_envs.env:SlamEnv", {"sequence": name}) for name in registered_names()]
    for env_id, entry_point, kwargs in entries:
        if env_id not in gymnasium.registry:
            gymnasium.register(id=env_id, entry_point=entry_point, kwargs=kwargs)
        ids.append(env_id)
    return ids


ENV_IDS: tuple[str, ...] = tuple(_register_envs())
