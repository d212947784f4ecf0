"""The simulated camera: known answers for rolling shutter, blur, response and vignetting, distortion, noise, exposure
control and depth noise; determinism; presets. Geometry tests use a synthetic render callback (no OpenGL)."""

from dataclasses import replace

import cv2
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from sim_envs.camera import Intrinsics, pinhole_maps, preset_distortion
from sim_envs.errors import SimEnvError, UnknownNameError
from sim_envs.motion.trajectories import Trajectory
from sim_envs.sensor.camera_effects import (
    ICL_READ_NOISE,
    ICL_SHOT_NOISE,
    CameraEffects,
    auto_exposure,
    camera_effect_presets,
    camera_effects_preset,
    decode_render,
    distortion_maps,
    expose,
    inverse_response,
    kinect_depth,
    linear_noise,
    sensor_geometry,
    sensor_image,
    undistort_image,
    vignette,
    with_options,
)
from sim_envs.sequences import SequenceSpec, get_sequence, with_camera
from sim_envs.sources.simsource import SimulatedSequence

W, H = 64, 48
K = Intrinsics(60.0, 60.0, 31.5, 23.5, W, H)
BRIGHT, DARK = 200, 40


def _edge_image(u_edge: float) -> np.ndarray:
    """(H, W, 3) uint8: BRIGHT left of the vertical line u = u_edge, DARK right of it, anti-aliased by pixel area
    (pixel u covers [u - 0.5, u + 0.5]) in the linear domain."""
    cover = np.clip(u_edge - (np.arange(W) - 0.5), 0.0, 1.0)  # bright share of each column
    lin_b, lin_d = decode_render(np.array([BRIGHT, DARK], np.uint8))
    lin = lin_d + cover * (lin_b - lin_d)
    enc = np.clip(np.rint(np.where(lin <= 0.0031308, 12.92 * lin, 1.055 * lin ** (1 / 2.4) - 0.055) * 255), 0, 255)
    return np.broadcast_to(enc.astype(np.uint8)[None, :, None], (H, W, 3)).copy()


def _edge_positions(rgb: np.ndarray) -> np.ndarray:
    """(H,) sub-pixel edge position of each row: the bright share summed over columns, in the linear domain."""
    lin = decode_render(rgb).mean(axis=2)
    lin_b, lin_d = decode_render(np.array([BRIGHT, DARK], np.uint8))
    return ((lin - lin_d) / (lin_b - lin_d)).sum(axis=1) - 0.5


def _geometry_camera(**kwargs) -> CameraEffects:
    """A camera that only moves pixels: exposure = reference (no brightness change), no noise, sRGB response."""
    exposure = kwargs.pop("exposure_s", 1e-6)
    return CameraEffects(exposure_s=exposure, reference_exposure_s=exposure, **kwargs)


def _moving_edge(speed_px_s: float):
    """A render callback and pose_at where time is stored in T[0, 3] and the edge moves at speed_px_s."""

    def pose_at(times):
        T = np.tile(np.eye(4), (len(times), 1, 1))
        T[:, 0, 3] = times
        return T

    return (lambda T: _edge_image(20.0 + speed_px_s * T[0, 3])), pose_at


def test_rolling_shutter_skew_under_a_known_yaw_speed():
    omega, readout = 2.0, 0.03  # rad/s about the camera's y axis (down), seconds from first to last row
    t = np.linspace(0.0, 2.0, 61)
    T = np.tile(np.eye(4), (61, 1, 1))
    T[:, :3, :3] = Rotation.from_euler("y", omega * (t - 1.0)[:, None]).as_matrix()
    trajectory = Trajectory(t, T, kind="yaw")

    def render(T_world_cam):  # a vertical edge at the world direction +z (the camera's forward at t = 1 s)
        d_cam = T_world_cam[:3, :3].T @ np.array([0.0, 0.0, 1.0])
        return _edge_image(K.cx + K.fx * d_cam[0] / d_cam[2])

    fx = _geometry_camera(blur_subframes=9, readout_s=readout)
    rgb = sensor_image(render, trajectory.pose_at, 1.0, fx, K, np.random.default_rng(0))
    rows = _edge_positions(rgb)
    slope = np.polyfit(np.arange(H), rows, 1)[0]
    # row 0 at t - readout/2, row H-1 at t + readout/2: u = cx - f tan(omega dt)
    expected = -K.fx * 2 * np.tan(omega * readout / 2) / (H - 1)
    assert slope * (H - 1) == pytest.approx(expected * (H - 1), abs=0.05)
    assert abs(expected * (H - 1)) > 3.0  # the skew is several pixels
    # the middle row sees the frame's own pose (the edge at cx)
    assert rows[H // 2 - 1 : H // 2 + 1].mean() == pytest.approx(K.cx, abs=0.1)
    # a global shutter has no skew
    still = sensor_image(render, trajectory.pose_at, 1.0, _geometry_camera(blur_subframes=9), K,
                         np.random.default_rng(0))  # fmt: skip
    assert np.ptp(_edge_positions(still)) < 0.02


def test_blur_length_under_known_speed_and_exposure():
    speed, exposure = 400.0, 0.02  # px/s and s: a blur of 8 px
    render, pose_at = _moving_edge(speed)
    fx = _geometry_camera(blur_subframes=33, exposure_s=exposure)
    rgb = sensor_image(render, pose_at, 0.0, fx, K, np.random.default_rng(0))
    lin = decode_render(rgb).mean(axis=2)[H // 2]
    lin_b, lin_d = decode_render(np.array([BRIGHT, DARK], np.uint8))
    slope = -np.diff((lin - lin_d) / (lin_b - lin_d))  # the blurred step's derivative: a box of the blur length
    centre = (slope * np.arange(len(slope))).sum() / slope.sum()
    variance = (slope * (np.arange(len(slope)) - centre) ** 2).sum() / slope.sum()
    length = np.sqrt(12 * variance - 1.0)  # box variance L^2/12 plus the one-pixel anti-aliasing box's 1/12
    assert length == pytest.approx(speed * exposure, rel=0.05)
    assert centre + 0.5 == pytest.approx(20.0, abs=0.1)  # the exposure is centred on the frame's time


def test_response_and_vignette_round_trip():
    L = np.random.default_rng(1).uniform(0.01, 0.9, (H, W, 3)).astype(np.float32)
    for fx in (CameraEffects(vignette_corner=0.6), CameraEffects(response="gamma", response_gamma=2.2,
                                                                 vignette_corner=0.6)):  # fmt: skip
        V = vignette(K, fx.vignette_corner)
        rgb = expose(L, fx, fx.reference_exposure_s, 1.0, np.random.default_rng(0), V)
        G = inverse_response(fx)
        assert G[0] == 0.0 and G[255] == pytest.approx(255.0) and (np.diff(G) > 0).all()
        recovered = G[rgb] / 255.0 / V[..., None]
        step = np.maximum(np.abs(np.gradient(G))[rgb], np.abs(np.gradient(G))[np.minimum(rgb + 1, 255)])
        assert (np.abs(recovered - L) <= 0.5 * step / 255.0 / V[..., None] + 1e-6).all()
    V = vignette(K, 0.6)
    assert V.max() == pytest.approx(1.0, abs=1e-3) and V.min() == pytest.approx(0.6, abs=0.01)


def test_distortion_round_trip_against_opencv():
    dist = np.asarray(preset_distortion("tum_fr1"))
    map_u, map_v = distortion_maps(K, tuple(dist))
    # the pinhole pixel each distorted pixel reads projects (OpenCV's forward model) back onto that pixel
    vs, us = np.mgrid[4:H - 4:5, 4:W - 4:5]  # fmt: skip
    pin = np.stack([map_u[vs, us], map_v[vs, us]], -1).reshape(-1, 2).astype(np.float64)
    rays = np.column_stack([(pin[:, 0] - K.cx) / K.fx, (pin[:, 1] - K.cy) / K.fy, np.ones(len(pin))])
    projected, _ = cv2.projectPoints(rays, np.zeros(3), np.zeros(3), K.K, dist)
    np.testing.assert_allclose(projected.reshape(-1, 2), np.column_stack([us.ravel(), vs.ravel()]), atol=1e-3)
    # and cv2.undistortPoints of the distorted pixels gives the same pinhole pixels
    und = cv2.undistortPoints(np.column_stack([us.ravel(), vs.ravel()]).astype(np.float64)[:, None], K.K, dist,
                              P=K.K).reshape(-1, 2)  # fmt: skip
    np.testing.assert_allclose(und, pin, atol=1e-3)
    # image round trip: distort, then undistort as a real distorted folder is: the pinhole image of the delivered
    # (cropped) camera, every pixel of which the lens saw
    img = cv2.GaussianBlur(np.random.default_rng(0).integers(0, 256, (H, W, 3)).astype(np.uint8), (0, 0), 2.0)
    geometry = sensor_geometry(K, CameraEffects(distortion=tuple(dist)))
    assert geometry.delivered.fx > K.fx and geometry.delivered.fy > K.fy  # a zoom, not K: no border without image
    for maps, size in ((geometry.undistort, (W, H)), (geometry.ground_truth, (W, H))):
        assert maps[0].min() >= 0 and maps[0].max() <= size[0] - 1 and maps[1].min() >= 0
        assert maps[1].max() <= size[1] - 1
    distorted = cv2.remap(img, *geometry.distort, cv2.INTER_LINEAR)
    back = undistort_image(distorted, geometry)
    expected = cv2.remap(img, *pinhole_maps(K, geometry.delivered), cv2.INTER_LINEAR)
    inner = (slice(3, H - 3), slice(3, W - 3))
    assert np.abs(back[inner].astype(int) - expected[inner].astype(int)).mean() < 2.0
    assert back.min(axis=2)[[0, -1]].max() > 0 and back.min(axis=2)[:, [0, -1]].max() > 0  # no black frame


def test_a_distorted_camera_delivers_the_pinhole_image_of_its_crop():
    """A lens-only camera's delivered frame against a pinhole render at the delivered intrinsics, same pose: the
    RGB agrees up to two bilinear resamplings, and the ground-truth depth is on the same pixel grid."""
    from sim_envs.render import make_renderer

    base = _tiny(get_sequence("office1"))
    effects = replace(camera_effects_preset("clean"), name="lens", distortion=preset_distortion("tum_fr1"))
    seq = SimulatedSequence(replace(base, camera_effects=effects))
    renderer = None
    try:
        assert seq.intrinsics == sensor_geometry(seq.sensor_intrinsics, effects).delivered != seq.sensor_intrinsics
        frame = seq.frame(4)
        renderer = make_renderer(seq.scene, seq.intrinsics)
        truth = renderer.render(seq.poses[4])
        assert np.abs(frame.rgb.astype(int) - truth.rgb.astype(int)).mean() < 6.0
        same = np.isclose(frame.depth, truth.depth, rtol=0.02)
        assert same.mean() > 0.95  # nearest-neighbour resampling differs only at depth edges
        assert (frame.rgb.max(axis=2) > 0).all()  # the lens saw every delivered pixel
    finally:
        seq.close()
        if renderer is not None:
            renderer.close()
    barrel = replace(effects, distortion=(-0.3, 0.1, 0.0, 0.0, 0.0))  # sees wider than the render: refused at once
    with pytest.raises(SimEnvError, match="wider than the rendered pinhole camera"):
        SimulatedSequence(replace(base, camera_effects=barrel))


def test_noise_statistics_in_the_linear_domain():
    fx = CameraEffects(shot_noise=ICL_SHOT_NOISE, read_noise=ICL_READ_NOISE)
    for level in (0.05, 0.5):
        flat = np.full((200, 200, 3), level, np.float32)
        noisy = linear_noise(flat, fx, np.random.default_rng(3))
        expected = np.sqrt(np.asarray(ICL_SHOT_NOISE) ** 2 * level + np.asarray(ICL_READ_NOISE) ** 2)
        np.testing.assert_allclose(noisy.std(axis=(0, 1)), expected, rtol=0.10)
        np.testing.assert_allclose(noisy.mean(axis=(0, 1)), level, atol=1e-3)


def test_auto_exposure_follows_brightness_with_a_lag():
    fx = CameraEffects(auto_exposure=True, ae_target=0.2, ae_rate=0.25, ae_max_s=0.1, max_gain=2.0)
    brightness = np.r_[np.full(20, 0.2), np.full(40, 0.1)]  # the room gets half as bright at frame 20
    exposure, gain = auto_exposure(brightness, fx)
    ref = fx.reference_exposure_s
    assert exposure[:21] == pytest.approx(ref)  # settled, and frame 20 was exposed before the change was seen
    assert ref < exposure[21] < exposure[25] < 2 * ref  # a lag, not a jump
    assert exposure[21] == pytest.approx(ref * 2**0.25)  # first-order step: (target / measured) ** rate
    assert exposure[-1] == pytest.approx(2 * ref, rel=1e-3) and (gain == 1).all()
    # frame i depends on frames before it only
    e5, _ = auto_exposure(brightness[:25], fx)
    np.testing.assert_array_equal(e5, exposure[:25])
    # in the dark the exposure stops at ae_max_s and the gain takes over, up to max_gain
    e_dark, g_dark = auto_exposure(np.full(200, 0.001), fx)
    assert e_dark[-1] == pytest.approx(0.1) and g_dark[-1] == pytest.approx(2.0)
    off_e, off_g = auto_exposure(brightness, CameraEffects(exposure_s=0.01))
    assert (off_e == 0.01).all() and (off_g == 1).all()


def test_same_seed_same_bytes_and_clean_is_identity():
    render, pose_at = _moving_edge(300.0)
    fx = camera_effects_preset("hard")
    a = sensor_image(render, pose_at, 0.1, fx, K, np.random.default_rng(7), exposure_s=0.02, gain=2.0)
    b = sensor_image(render, pose_at, 0.1, fx, K, np.random.default_rng(7), exposure_s=0.02, gain=2.0)
    c = sensor_image(render, pose_at, 0.1, fx, K, np.random.default_rng(8), exposure_s=0.02, gain=2.0)
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)
    clean = camera_effects_preset("clean")
    assert not clean.any and clean == CameraEffects(name="clean")
    img = render(pose_at(np.array([0.1]))[0])
    np.testing.assert_array_equal(sensor_image(render, pose_at, 0.1, clean, K, np.random.default_rng(0)), img)


def test_noise_drawn_ahead_gives_the_same_bytes():
    from sim_envs.sensor.camera_effects import noise_draws

    render, pose_at = _moving_edge(300.0)
    fx = camera_effects_preset("kinect")
    serial = sensor_image(render, pose_at, 0.1, fx, K, np.random.default_rng(7), exposure_s=0.02, gain=1.5)
    rng = np.random.default_rng(7)
    drawn = noise_draws((K.height, K.width, 3), fx, rng)
    ahead = sensor_image(render, pose_at, 0.1, fx, K, rng, exposure_s=0.02, gain=1.5, normals=lambda: drawn)
    np.testing.assert_array_equal(serial, ahead)
    assert noise_draws((4, 4, 3), CameraEffects(), np.random.default_rng(0)) is None  # no noise: no draw
    with pytest.raises(ValueError, match="rng or normals"):
        linear_noise(np.zeros((2, 2, 3), np.float32), fx)


def test_exposures_are_the_same_in_any_order_of_asking():
    spec = with_camera(_tiny(get_sequence("office1"), 40), "kinect")
    whole, pieces = SimulatedSequence(spec), SimulatedSequence(spec)
    try:
        e_all, g_all = whole.exposures()
        for upto in (0, 3, 17, 2, 39):  # the cache grows by doubling and keeps every value it gave
            e, g = pieces.exposures(upto)
            np.testing.assert_array_equal(e, e_all[: upto + 1])
            np.testing.assert_array_equal(g, g_all[: upto + 1])
        e[:] = -1  # a copy: the caller cannot change the cache
        assert (pieces.exposures(5)[0] > 0).all()
    finally:
        whole.close()
        pieces.close()


def test_presets_and_unknown_names():
    assert camera_effect_presets() == ["clean", "fr1", "hard", "kinect"]
    kinect = camera_effects_preset("kinect")
    assert kinect.shot_noise == ICL_SHOT_NOISE and kinect.read_noise == ICL_READ_NOISE and kinect.auto_exposure
    assert camera_effects_preset("hard").distortion == preset_distortion("tum_fr1")
    with pytest.raises(UnknownNameError, match="valid presets: clean, fr1, hard, kinect"):
        camera_effects_preset("fancy")
    with pytest.raises(UnknownNameError, match="clean, fr1, hard, kinect"):
        with_camera(get_sequence("office0"), "fancy")
    spec = with_camera(get_sequence("office0"), "kinect")
    assert spec.camera_effects == "kinect" and "kinect" in repr(spec) and spec != get_sequence("office0")
    assert get_sequence("office0").camera_effects == "clean"  # registered sequences keep today's images
    weaker = with_options(kinect, blur_subframes=1)
    assert weaker.name == "kinect+blur_subframes=1" and weaker.describe()["shot_noise"] == list(ICL_SHOT_NOISE)


@pytest.mark.parametrize("kwargs", [{"vignette_corner": 0.0}, {"ae_rate": 0.0}, {"blur_subframes": 0},
                                    {"shot_noise": (1.0, 2.0)}, {"response": "log"}, {"max_gain": 0.5},
                                    {"readout_s": -1.0}, {"distortion": (1.0, 2.0)}])  # fmt: skip
def test_bad_settings_are_rejected(kwargs):
    with pytest.raises(SimEnvError):
        CameraEffects(**kwargs)


def test_kinect_depth_quantises_jitters_and_leaves_holes_at_edges():
    depth = np.full((60, 80), 2.0, np.float32)
    depth[:, 40:] = 3.0  # a depth edge
    depth[0, 0] = 0.0
    before = depth.copy()
    out = kinect_depth(depth, np.random.default_rng(0))
    np.testing.assert_array_equal(depth, before)  # the ground truth is not touched
    assert (out[:, 37:43] == 0).mean() > 0.5  # holes along the edge
    flat = out[5:-5, 5:30]
    assert (flat > 0).all() and abs(np.median(flat) - 2.0) < 0.03
    assert len(np.unique(flat)) <= 6  # disparity quantisation: a few depth levels, not a continuum
    np.testing.assert_array_equal(out, kinect_depth(depth, np.random.default_rng(0)))


def _tiny(spec: SequenceSpec, n: int = 12) -> SequenceSpec:
    return replace(spec.with_frames(n), width=64, height=48)


def test_a_rendered_sequence_through_each_camera():
    base = _tiny(get_sequence("office1"))
    clean, default = SimulatedSequence(with_camera(base, "clean")), SimulatedSequence(base)
    kinect_a, kinect_b = SimulatedSequence(with_camera(base, "kinect")), SimulatedSequence(with_camera(base, "kinect"))
    hard = SimulatedSequence(with_camera(base, "hard"))
    try:
        f_clean = clean.frame(6)
        np.testing.assert_array_equal(f_clean.rgb, default.frame(6).rgb)  # clean: today's bytes
        assert f_clean.sensor_depth is None
        fa = [kinect_a.frame(i) for i in (6, 2)]
        fb = [kinect_b.frame(i) for i in (2, 6)][::-1]  # another order, another instance: the same bytes
        for x, y in zip(fa, fb, strict=True):
            np.testing.assert_array_equal(x.rgb, y.rgb)
            np.testing.assert_array_equal(x.sensor_depth, y.sensor_depth)
        np.testing.assert_array_equal(fa[0].depth, f_clean.depth)  # ground truth untouched
        np.testing.assert_array_equal(fa[0].labels, f_clean.labels)
        assert not np.array_equal(fa[0].rgb, f_clean.rgb) and fa[0].sensor_depth.shape == f_clean.depth.shape
        np.testing.assert_array_equal(kinect_a.rgb(6), fa[0].rgb)
        exposure, gain = kinect_a.exposures()
        assert exposure.shape == (12,) and (exposure > 0).all() and (gain >= 1).all()
        assert not np.array_equal(hard.raw_rgb(6), hard.rgb(6))  # the lens distorts the raw image
        np.testing.assert_array_equal(kinect_a.raw_rgb(6), fa[0].rgb)  # no distortion: raw is delivered
    finally:
        for s in (clean, default, kinect_a, kinect_b, hard):
            s.close()


def test_export_writes_the_photometric_calibration(tmp_path):
    from sim_envs.folders.datasets import export_tum_rgbd, load_rgbd_folder, read_camera_file

    seq = SimulatedSequence(with_camera(_tiny(get_sequence("office0"), 6), "hard"))
    try:
        export_tum_rgbd(seq, tmp_path, progress=False)
        exposure, gain = seq.exposures()
        times = np.loadtxt(tmp_path / "times.txt")
        assert times.shape == (6, 3)
        np.testing.assert_allclose(times[:, 1], seq.timestamps, atol=1e-6)
        np.testing.assert_allclose(times[:, 2], exposure * gain * 1000, rtol=1e-6)
        G = np.loadtxt(tmp_path / "pcalib.txt")
        np.testing.assert_allclose(G, inverse_response(seq.camera_effects), atol=1e-5)
        V = cv2.imread(str(tmp_path / "vignette.png"), cv2.IMREAD_UNCHANGED)
        assert V.dtype == np.uint16 and V.shape == (48, 64) and V.max() > 60000 and V[24, 32] > V[2, 2]
        assert not read_camera_file(tmp_path / "camera.toml").distorted
        assert read_camera_file(tmp_path / "camera_raw.toml").distortion == preset_distortion("tum_fr1")
        assert len(list((tmp_path / "depth_sensor").iterdir())) == 6
        loaded = load_rgbd_folder(tmp_path, size=None)
        np.testing.assert_array_equal(loaded.frame(3).rgb, seq.rgb(3))  # the exported images are the delivered ones
    finally:
        seq.close()


def test_one_effect_alone_by_name():
    from sim_envs.errors import SimEnvError
    from sim_envs.sensor.camera_effects import FPS_NOMINAL, SINGLE_EFFECTS, single_effect

    kinect = camera_effects_preset("kinect")
    noise = camera_effects_preset("noise:2")
    assert noise.name == "noise:2" and noise.shot_noise == pytest.approx(tuple(2 * v for v in ICL_SHOT_NOISE))
    assert noise.read_noise == pytest.approx(tuple(2 * v for v in ICL_READ_NOISE)) and noise.sensor_width == 640
    assert not noise.auto_exposure and noise.blur_subframes == 1 and not noise.distorted
    blur = camera_effects_preset("blur:2")  # the whole frame interval, brightness unchanged
    assert blur.exposure_s == pytest.approx(1 / FPS_NOMINAL) and not blur.photometric and blur.readout_s == 0
    rs = camera_effects_preset("rolling_shutter:0.5")
    assert rs.readout_s == pytest.approx(0.5 / FPS_NOMINAL) and rs.exposure_s == 1e-3 and not rs.photometric
    exposure = camera_effects_preset("exposure:3")
    assert exposure.auto_exposure and exposure.exposure_jitter == pytest.approx(3 * kinect.exposure_jitter)
    assert not any(exposure.shot_noise) and exposure.blur_subframes == 1 and not exposure.depth_noise
    dist = camera_effects_preset("distortion:0.5")
    assert dist.distortion == pytest.approx(tuple(0.5 * c for c in preset_distortion("tum_fr1")))
    assert all(not single_effect(e, 0).any for e in SINGLE_EFFECTS)  # strength 0: the clean camera's bytes
    with pytest.raises(UnknownNameError, match="EFFECT:STRENGTH with EFFECT one of noise, blur"):
        camera_effects_preset("glare:1")
    with pytest.raises(SimEnvError, match="strength after ':' must be a number"):
        camera_effects_preset("noise:lots")
    with pytest.raises(SimEnvError, match="at most 2"):
        camera_effects_preset("blur:3")
    with pytest.raises(SimEnvError, match=">= 0"):
        single_effect("noise", -1)
    spec = with_camera(get_sequence("office0"), "noise:2")
    assert spec.camera_effects_model() == noise  # a spec names it by string, so it enters the run fingerprint
