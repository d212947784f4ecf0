"""The camera's bytes, pinned: sha256 digests of what ``clean``, ``kinect``, ``hard`` and each single effect at strength
1 make, so that a restructuring of the camera's code is seen to give the same bytes. Two tiers: a synthetic scene
through :func:`sim_envs.sensor.camera_effects.sensor_image` (no OpenGL), and 6 rendered frames of office0 at 320x240
through :class:`sim_envs.sources.simsource.SimulatedSequence`, the frame source the suites use (slow; skipped where
this machine's renderer gives other clean bytes than the recording's). Bytes are pinned per CPU (the tests'
``pinned_bytes``): vectorised sin/cos and OpenCV's kernels round differently on another instruction set. On every
CPU the synthetic tier's figures (mean, standard deviation and mean horizontal change of each output, and of each
image's difference from the clean camera's) are checked within a tolerance that a 1.1x stronger effect exceeds
(``camera_effects_figures.json``; ``PYTHONPATH=. python tests/sim_envs/test_camera_effects_bytes.py`` records them
again)."""

import hashlib
import json
from pathlib import Path

import numpy as np
import pytest

from sim_envs.camera import Intrinsics
from sim_envs.sensor.camera_effects import (
    auto_exposure,
    camera_effects_preset,
    inverse_response,
    kinect_depth,
    mean_brightness,
    sensor_geometry,
    sensor_image,
    undistort_image,
)

CAMERAS = ("clean", "kinect", "hard", "noise:1", "blur:1", "exposure:1", "rolling_shutter:1", "distortion:1")
W, H = 64, 48
K = Intrinsics(60.0, 60.0, 31.5, 23.5, W, H)

# sha256 of the synthetic tier (test_synthetic_camera_bytes), per CPU (the tests' cpu_label; "unrecorded": the first
# machine's, whose CPU was not written down), per camera; on the AMD EPYC every synthetic digest differs from the first
# machine's, of the rendered ones only kinect's
SYNTHETIC = {
    "unrecorded": {
        "clean": "6707c47cf29c9b88e2ae4c9404040b9fa8698c5ce07e6809c92e50adb6604dd6",
        "kinect": "10536efbea2b4a444017a4698e80c821f3bb0b3e7dbfd892715065f406906670",
        "hard": "d9d8efeded971856248427167d2bfde4817d961017c4e458f71e6c31d5376d7c",
        "noise:1": "1c43f4936c37ae7ad3789db9812d500a7e69a4eaec801eed5cbd4ef00ea2a81b",
        "blur:1": "2eda80f28242b2406cd48bbcb79967c529657eea3f90de67c7eb344da9b932cb",
        "exposure:1": "f0086af97ecf3f5f3d22866021cbbf087caa958ddfa32805d1779b7338cb07f8",
        "rolling_shutter:1": "0fc0d5fa6b07771d2ec18f6bd65497382e7e22395a5f654b2b1a6ede09508035",
        "distortion:1": "52259a5249647d1fe00b3248592830c8c1ae454a2e14cbff95459fccae7a0618",
        "fr1": "249a7bf83614b67fe9255effc4b0cd18790a68f3cbbd87e208aeaa63da232ae3",  # synthetic tier only
    },
    "AMD EPYC, avx2": {
        "clean": "b4f2551b79b24ea50b5b72eb95f9e8e612d55b2a5813b9f8a4164dacd936e884",
        "kinect": "d29f5a858d25a315d0643e7aa5ad8069f57a1af97863b705d7ac031a5c2b5afe",
        "hard": "ec73642d1221f5856b6149d6d869a7eb3de10a2e2dea6e530a91c14dbc01badb",
        "noise:1": "69e83302de6e76bb30916b4dd2e25d81927e79812d006a0afc41ebef1832b282",
        "blur:1": "09c8d93de888835bc03f537af3f9bfab76d601b6e0d9f1484c24e9b86e9d1227",
        "exposure:1": "20acf3d9877c5915c0aa9da7efed3bf4aebe03aa915c2c0ddfc1d4a1116c6fe7",
        "rolling_shutter:1": "6b11556729c0489dd346c164ac36d2e789eefc0668b2dcbc45cda0e402761888",
        "distortion:1": "21cec2c9a2904ffdad77a86d21b96bb79adc51a2724c1b079be0c5b96543f467",
        "fr1": "01c63cde41e2ac47561c4d515c63e4cd6798e079b9e76bde9627c99d31a7e38b",
    },
}
FIGURES = Path(__file__).with_name("camera_effects_figures.json")  # the synthetic tier's figures, per camera
FIGURES_ATOL, FIGURES_RTOL = 0.02, 2e-4  # grey levels (and seconds, gains), relative
# sha256 of 6 rendered frames of office0 at 320x240 (rgb and sensor depth of each, the exposures and gains, the raw
# image of frame 5), per camera, recorded with MUJOCO_GL=egl; CLEAN_RENDERS: the clean camera's rgb alone (the
# renderer's own bytes)
RENDERED = {
    "clean": "1c1eac48b887e540ea4873e5d7ce7ca9b974d4155345ba744e467851f1b43449",
    "kinect": "0bfa9ba3511e6f59e9c316e04ff8c4870248d431b676a5d8105ec18750833a50",
    "hard": "d10acc93e905c160e6cad2149ad9e3655ae73f0fc3b6e51458c7cab2a9e5d87d",
    "noise:1": "d043348a72b8fd11a2e40883b43de70d7f435f748cf372db0a295af9fd9ee51c",
    "blur:1": "a6186c5734dd7077c252bc0f7ced70d935973f06eea38aa7f7f2500f6ee56808",
    "exposure:1": "743ab5195d6f80f0b1424da9e65f529c88ef68882bdecef9025caa92e9180b21",
    "rolling_shutter:1": "a611e76fe0ef230650c545d3ef4af9948dd93c742f76d327330dbb15dcbe90bc",
    "distortion:1": "43808d755def405f34f7cb24a577d9a07a7df2e78c6815d892183a980b1c41b3",
}
CLEAN_RENDERS = "0fe451029abecc5ae3d919c8e60cda7a7daad887eee54a92c1c849b9bc142567"
RENDERED_ON = {"unrecorded": RENDERED, "AMD EPYC, avx2": RENDERED | {
    "kinect": "73fb9b24592300af3240b32bce0bfc35620a9d076d411b411e6dc820fd28cd5f"}}


def _synthetic_render(T: np.ndarray) -> np.ndarray:
    """(H, W, 3) uint8 of a textured plane shifted by the pose's translation (x, y in pixels), no OpenGL."""
    u, v = np.meshgrid(np.arange(W, dtype=np.float64), np.arange(H, dtype=np.float64))
    u, v = u - 40.0 * T[0, 3], v - 25.0 * T[1, 3]
    base = 128 + 90 * np.sin(u / 3.0) * np.cos(v / 5.0)
    rgb = np.stack([base, 0.7 * base + 30 * np.sin(v / 2.0), 255 - base], axis=-1)
    return np.clip(np.rint(rgb), 0, 255).astype(np.uint8)


def _pose_at(times: np.ndarray) -> np.ndarray:
    T = np.tile(np.eye(4), (len(times), 1, 1))
    T[:, 0, 3], T[:, 1, 3] = 3.0 * times, -1.5 * times
    return T


def _synthetic_outputs(name: str) -> list[np.ndarray]:
    """Everything the camera ``name`` computes for a synthetic 4-frame scene: the auto-exposure series (brightness,
    exposure, gain), the response table, each frame's raw and delivered image, and a Kinect-like depth where the
    camera has depth noise."""
    fx = camera_effects_preset(name)
    geometry = sensor_geometry(K, fx)
    times = np.arange(4) / 30.0
    brightness = [mean_brightness(_synthetic_render(T), fx, geometry.vignette) for T in _pose_at(times)]
    jitter = np.random.default_rng(5).standard_normal(4)
    exposure, gain = auto_exposure(np.asarray(brightness), fx, jitter)
    out = [np.asarray(brightness), exposure, gain, inverse_response(fx)]
    for i, t in enumerate(times):
        raw = sensor_image(_synthetic_render, _pose_at, float(t), fx, K, np.random.default_rng((9, i)),
                           exposure_s=float(exposure[i]), gain=float(gain[i]), geometry=geometry)  # fmt: skip
        out += [raw, undistort_image(raw, geometry)]
    if fx.depth_noise:
        depth = (1.0 + 0.01 * _synthetic_render(np.eye(4))[..., 0]).astype(np.float32)
        out.append(kinect_depth(depth, np.random.default_rng(3)))
    return out


def _synthetic_digest(name: str) -> str:
    """sha256 over the camera's parameters and :func:`_synthetic_outputs`."""
    h = hashlib.sha256(json.dumps(camera_effects_preset(name).describe(), sort_keys=False).encode())
    for a in _synthetic_outputs(name):
        h.update(a.tobytes())
    return h.hexdigest()


IMAGES = slice(4, 12)  # the raw and delivered images among _synthetic_outputs


def _synthetic_figures(name: str) -> list[float]:
    """Per output of :func:`_synthetic_outputs`: mean, standard deviation and (images, depth) mean absolute change
    between horizontal neighbours; then per image the mean and standard deviation of its difference from the clean
    camera's (the effect alone: the noise, the blur's smoothing, the shutter's shift)."""
    outputs = _synthetic_outputs(name)
    figures = []
    for a in outputs:
        a = np.asarray(a, np.float64)
        figures += [a.mean(), a.std()] + ([np.abs(np.diff(a, axis=1)).mean()] if a.ndim >= 2 else [])
    for a, clean in zip(outputs[IMAGES], _synthetic_outputs("clean")[IMAGES], strict=True):
        d = a.astype(np.float64) - clean
        figures += [d.mean(), d.std()]
    return [float(f) for f in figures]


def _within(got: list[float], want: list[float]) -> bool:
    return len(got) == len(want) and bool(np.all(np.abs(np.subtract(got, want)) <= FIGURES_ATOL + FIGURES_RTOL *
                                                 np.abs(want)))


@pytest.mark.parametrize("name", (*CAMERAS, "fr1"))
def test_synthetic_camera_bytes(name, pinned_bytes):
    digest = _synthetic_digest(name)
    assert digest == pinned_bytes(digest, {cpu: d[name] for cpu, d in SYNTHETIC.items()},
                                  "test_synthetic_camera_figures")  # fmt: skip


@pytest.mark.parametrize("name", (*CAMERAS, "fr1"))
def test_synthetic_camera_figures(name):
    # any CPU: within 0.02 grey levels + 0.02 % of the recorded figures; scaling the scene's texture by 1 + 1e-4,
    # which moves 25 of its 9216 values by one level, moves them by 0.17 of that, a 1.02x stronger effect by 0.4-16
    want = json.loads(FIGURES.read_text())[name]
    got = _synthetic_figures(name)
    off = [abs(g - w) / (FIGURES_ATOL + FIGURES_RTOL * abs(w)) for g, w in zip(got, want, strict=True)]
    assert _within(got, want), f"figure {int(np.argmax(off))} of {len(want)} off by {max(off):.2f} tolerances"


@pytest.mark.parametrize("effect", ("noise", "blur", "exposure", "rolling_shutter", "distortion"))
def test_the_figures_tell_an_effect_a_tenth_stronger(effect):
    recorded = json.loads(FIGURES.read_text())[f"{effect}:1"]
    assert not _within(_synthetic_figures(f"{effect}:1.1"), recorded)


def _rendered_digests(name: str) -> tuple[str, str]:
    """(digest of the camera's outputs, digest of its rgb frames alone) for 6 frames of office0 through ``name``."""
    from sim_envs.sequences import get_sequence, with_camera
    from sim_envs.sources.simsource import SimulatedSequence

    spec = with_camera(get_sequence("office0").with_frames(6), name)
    assert (spec.width, spec.height) == (320, 240)
    every, rgb = hashlib.sha256(), hashlib.sha256()
    with SimulatedSequence(spec) as seq:
        for i in range(6):
            frame = seq.frame(i)
            every.update(frame.rgb.tobytes())
            rgb.update(frame.rgb.tobytes())
            if frame.sensor_depth is not None:
                every.update(frame.sensor_depth.tobytes())
        for a in seq.exposures():
            every.update(a.tobytes())
        every.update(seq.raw_rgb(5).tobytes())
    return every.hexdigest(), rgb.hexdigest()


@pytest.mark.slow
def test_rendered_camera_bytes(pinned_bytes):
    everything, clean_rgb = _rendered_digests("clean")
    if clean_rgb != CLEAN_RENDERS:
        pytest.skip("this machine's renderer (OpenGL backend or MuJoCo version) draws office0 with other bytes than "
                    "the recording's; the camera's own bytes are checked by test_synthetic_camera_bytes")  # fmt: skip
    got = {"clean": everything} | {name: _rendered_digests(name)[0] for name in CAMERAS[1:]}
    assert got == pinned_bytes(got, RENDERED_ON, "test_synthetic_camera_figures")


if __name__ == "__main__":  # record the synthetic tier's figures on this machine
    lines = (f"  {json.dumps(n)}: {json.dumps(_synthetic_figures(n))}" for n in (*CAMERAS, "fr1"))
    FIGURES.write_text("{\n" + ",\n".join(lines) + "\n}\n")
