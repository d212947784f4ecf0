"""The simulated world: procedural indoor scenes, offscreen renderers, camera trajectories, Gymnasium environments.

Knows nothing of SLAM. Conventions: camera x right, y down, z forward (OpenCV); poses ``T_world_cam`` 4x4;
depth metric planar z in metres (0 = no surface); images H x W.
"""
