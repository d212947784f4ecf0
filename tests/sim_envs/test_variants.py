"""The sweep's world variants: other focal lengths and an added pan about the camera's y axis."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from sim_envs.camera import preset
from sim_envs.errors import SimEnvError
from sim_envs.sequences import get_sequence
from sim_envs.sources.variants import ADDED_PAN_AMPLITUDE_DEG, VariantSequence


def test_variant_sequence_focal_and_pan():
    spec = get_sequence("office1").with_frames(90)
    plain = VariantSequence(spec)
    assert plain.trajectory is plain.trajectory and plain.intrinsics == spec.intrinsics()
    focal = VariantSequence(spec, name="f", focal_ratio=1.2)
    nyu = preset("nyu", spec.width, spec.height)
    assert focal.name == "f" and focal.intrinsics.fx == pytest.approx(1.2 * nyu.fx)
    assert focal.intrinsics.cx == spec.intrinsics().cx
    panned = VariantSequence(spec, added_pan_deg_s=30.0)
    base_T, pan_T = plain.poses, panned.poses
    np.testing.assert_allclose(pan_T[:, :3, 3], base_T[:, :3, 3])  # the optical centre keeps its path
    rel = Rotation.from_matrix(np.einsum("nji,njk->nik", base_T[:, :3, :3], pan_T[:, :3, :3]))
    angles = np.degrees(rel.as_rotvec())
    assert np.abs(angles[:, [0, 2]]).max() < 1e-6  # about the camera's y axis only
    assert np.abs(angles[:, 1]).max() == pytest.approx(ADDED_PAN_AMPLITUDE_DEG, abs=0.5)
    with pytest.raises(SimEnvError, match="focal_ratio"):
        VariantSequence(spec, focal_ratio=0.0)
