"""Third-party SLAM and odometry systems wrapped as ``sim_envs`` agents (reset / step / finish), so that the
benchmark suites run them like our own methods (method tables ``ORB-SLAM3`` and ``Open3D-odometry`` in
``eval/methods.toml``). Each is OPTIONAL: its package is an extra (``pip install -e '.[orbslam3]'``,
``'.[open3d]'``), and a suite skips the method, with the reason, where it is not installed.

- :mod:`thirdparty.orbslam3`: ORB-SLAM3 (GPL-3.0, through the ``pyorbslam3`` wheel), monocular. It runs OUT OF
  PROCESS: :mod:`thirdparty.orbslam3` never imports ``pyorbslam3``; it starts ``thirdparty/orbslam3_driver.py`` as a
  separate program and exchanges images and poses with it over pipes. Its ORB vocabulary is ours, built from
  simulated training frames (:mod:`thirdparty.orb_vocabulary`, ``thirdparty/vocabulary/``).
- :mod:`thirdparty.open3d_odometry`: Open3D's RGB-D odometry (MIT), in process; it needs the depth of an RGB-D
  camera.

Poses are ``T_world_cam`` (4, 4) float64 camera-to-world, OpenCV camera axes (x right, y down, z forward), as
everywhere in ``sim_envs``.
"""
