import numpy as np
import pytest

from sim_envs.camera import Intrinsics, camera_presets, preset
from sim_envs.errors import SimEnvError, UnknownNameError


def test_preset_scaled_to_default_resolution_keeps_pixel_centres():
    cam = preset("icl")
    assert (cam.width, cam.height) == (320, 240)
    assert cam.fx == pytest.approx(240.6) and cam.fy == pytest.approx(240.0)
    # (319.5 + 0.5) / 2 - 0.5: the image centre stays the image centre
    assert cam.cx == pytest.approx(159.5) and cam.cy == pytest.approx(119.5)


def test_scaling_round_trip_and_K():
    cam = Intrinsics(517.3, 516.5, 318.6, 255.3, 640, 480)
    back = cam.scaled(160, 120).scaled(640, 480)
    np.testing.assert_allclose(back.as_array(), cam.as_array())
    K = cam.K
    assert K.shape == (3, 3) and K[0, 0] == 517.3 and K[1, 2] == 255.3 and K[2, 2] == 1.0


def test_unknown_preset_lists_valid_names():
    with pytest.raises(UnknownNameError) as err:
        preset("kinect9")
    for name in camera_presets():
        assert name in str(err.value)


def test_bad_intrinsics_rejected():
    with pytest.raises(SimEnvError, match="negative fy"):
        Intrinsics(481.2, -480.0, 319.5, 239.5, 640, 480)
    with pytest.raises(SimEnvError, match="image size"):
        Intrinsics(1, 1, 0, 0, 0, 10)
