"""Both renderers on generated rooms: outputs, determinism, lazy contexts, pickling, agreement, GL platform choice."""

import os
import pickle
import sys

import numpy as np
import pytest

from sim_envs.camera import preset
from sim_envs.errors import RendererUnavailableError, SimEnvError, UnknownNameError
from sim_envs.frames import NO_INSTANCE, NO_LABEL, SemanticClass
from sim_envs.render import BACKENDS, OUTPUTS, make_renderer
from sim_envs.render import gl as glmod
from sim_envs.scenes.scenegen import TEST_STYLES, generate_scene

CAM = preset("icl")  # 320 x 240


def look_at(eye, target, up=(0.0, 0.0, 1.0)) -> np.ndarray:
    """(4, 4) T_world_cam with OpenCV axes (z forward, y down) at ``eye`` looking at ``target``."""
    eye = np.asarray(eye, dtype=float)
    z = np.asarray(target, dtype=float) - eye
    z /= np.linalg.norm(z)
    x = np.cross(z, up)
    x /= np.linalg.norm(x)
    T = np.eye(4)
    T[:3, :3] = np.stack([x, np.cross(z, x), z], axis=1)
    T[:3, 3] = eye
    return T


def views(scene, n, seed=0):
    """``n`` poses at free points of ``scene`` (eye height 1.2-1.7 m) looking at random interest points."""
    rng = np.random.default_rng(seed)
    targets = scene.interest_points()
    out = []
    while len(out) < n:
        eye = np.array([*rng.uniform([0, 0], scene.room_size[:2]), rng.uniform(1.2, 1.7)])
        target = targets[rng.integers(len(targets))]
        if scene.free_space(eye[None], margin=0.4)[0] and np.linalg.norm(target - eye) > 1.0:
            out.append(look_at(eye, target))
    return out


@pytest.fixture(scope="module", params=TEST_STYLES)
def room(request):
    scene = generate_scene(request.param, 0)
    return scene, views(scene, 4)


@pytest.fixture(scope="module")
def renders(room):
    """backend -> list of RenderOutput (all outputs) for the room's views."""
    scene, poses = room
    out = {}
    for backend in BACKENDS:
        with make_renderer(scene, CAM, backend) as renderer:
            out[backend] = [renderer.render(T) for T in poses]
    return out


def test_outputs_have_the_documented_types(renders):
    for backend, outs in renders.items():
        for o in outs:
            assert o.rgb.shape == (240, 320, 3) and o.rgb.dtype == np.uint8, backend
            assert o.depth.shape == (240, 320) and o.depth.dtype == np.float32
            assert o.labels.dtype == np.uint8 and o.instances.dtype == np.int32
            # a closed room: every pixel hits a surface, at a plausible indoor distance
            assert (o.depth > 0).all() and o.depth.max() < 12.0
            assert (o.labels != NO_LABEL).all() and (o.instances != NO_INSTANCE).all()


def test_all_four_classes_are_seen(renders):
    for backend, outs in renders.items():
        seen = set(np.unique(np.concatenate([o.labels.ravel() for o in outs])).tolist())
        assert seen == {int(c) for c in SemanticClass}, backend


def test_labels_are_the_classes_of_the_instances(room, renders):
    scene, _ = room
    classes = scene.instance_classes()
    for outs in renders.values():
        for o in outs:
            np.testing.assert_array_equal(o.labels, classes[o.instances])


def test_the_two_renderers_agree(renders):
    """Depth within 1 % on >= 99 % of the pixels both cover, and the same labels on >= 99 % of pixels."""
    for a, b in zip(renders["mujoco"], renders["pyrender"], strict=True):
        both = (a.depth > 0) & (b.depth > 0)
        rel = np.abs(a.depth - b.depth) / np.maximum(a.depth, 1e-6)
        depth_ok = (rel[both] < 0.01).mean()
        label_ok = (a.labels == b.labels).mean()
        print(f"depth agreement {depth_ok:.5f}, label agreement {label_ok:.5f}")
        assert both.mean() > 0.99
        assert depth_ok >= 0.99
        assert label_ok >= 0.99
        # the same lighting model: RGB agrees too, up to rasterisation at edges
        assert np.abs(a.rgb.astype(int) - b.rgb.astype(int)).mean() < 2.0


@pytest.mark.parametrize("backend", BACKENDS)
def test_rendering_is_deterministic_and_lazy(room, backend):
    scene, poses = room
    renderer = make_renderer(generate_scene(scene.style, 0), CAM, backend)
    blob = pickle.dumps(renderer)  # no OpenGL context yet: it travels to a spawned worker as a plain object
    copy = pickle.loads(blob)
    try:
        a = renderer.render(poses[0])
        b = copy.render(poses[0])
        for name in OUTPUTS:
            np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
        renderer.close()
        c = renderer.render(poses[0], outputs=("rgb",))  # a closed renderer opens again on demand
        np.testing.assert_array_equal(a.rgb, c.rgb)
        assert pickle.loads(pickle.dumps(renderer)).render(poses[0], ("depth",)).depth.tobytes() == a.depth.tobytes()
    finally:
        renderer.close()
        copy.close()


@pytest.mark.parametrize("backend", BACKENDS)
def test_only_requested_outputs_are_returned_and_equal_to_full_renders(room, renders, backend):
    scene, poses = room
    full = renders[backend][1]
    with make_renderer(scene, CAM, backend) as renderer:
        for wanted in [("rgb",), ("depth",), ("labels",), ("instances",), ("rgb", "depth"), ("depth", "labels")]:
            out = renderer.render(poses[1], wanted)
            for name in OUTPUTS:
                got = getattr(out, name)
                if name in wanted:
                    np.testing.assert_array_equal(got, getattr(full, name), err_msg=f"{wanted}: {name}")
                else:
                    assert got is None


def test_bad_arguments():
    scene = generate_scene("living", 1, settle=False)
    with pytest.raises(UnknownNameError) as err:
        make_renderer(scene, CAM, "blender")
    assert "mujoco" in str(err.value) and "pyrender" in str(err.value)
    with make_renderer(scene, CAM) as renderer:
        with pytest.raises(SimEnvError, match="valid outputs"):
            renderer.render(np.eye(4), outputs=("rgb", "normals"))
        with pytest.raises(SimEnvError, match="rotation"):
            renderer.render(np.diag([1.0, 1.0, -1.0, 1.0]))
        with pytest.raises(SimEnvError, match="4, 4"):
            renderer.render(np.eye(3))


# ------------------------------------------------------------------------------------------ GL platform selection
@pytest.fixture
def clean_gl_env(monkeypatch):
    """No platform chosen by the user, and PyOpenGL looking unimported (the real state is restored afterwards)."""
    monkeypatch.delenv("MUJOCO_GL", raising=False)
    monkeypatch.delenv("PYOPENGL_PLATFORM", raising=False)
    monkeypatch.delitem(sys.modules, "OpenGL.platform", raising=False)
    return monkeypatch


def test_egl_is_preferred(clean_gl_env):
    assert glmod.configure_gl(probe=lambda lib: True) == "egl"
    assert os.environ["MUJOCO_GL"] == "egl" and os.environ["PYOPENGL_PLATFORM"] == "egl"


def test_osmesa_is_the_fallback(clean_gl_env):
    assert glmod.configure_gl(probe=lambda lib: "OSMesa" in lib) == "osmesa"
    assert os.environ["MUJOCO_GL"] == "osmesa" and os.environ["PYOPENGL_PLATFORM"] == "osmesa"


def test_no_platform_gives_one_clear_error(clean_gl_env):
    with pytest.raises(RendererUnavailableError) as err:
        glmod.configure_gl(probe=lambda lib: False)
    message = str(err.value)
    for needle in ("libEGL.so.1", "libegl1", "libgl1-mesa-dri", "libOSMesa", "libosmesa6"):
        assert needle in message


def test_a_users_choice_is_respected(clean_gl_env):
    clean_gl_env.setenv("PYOPENGL_PLATFORM", "osmesa")

    def probe(lib):
        raise AssertionError("no probing when the user chose")

    assert glmod.configure_gl(probe=probe) == "osmesa"
    assert os.environ["MUJOCO_GL"] == "osmesa"
    clean_gl_env.setenv("MUJOCO_GL", "egl")
    with pytest.raises(RendererUnavailableError, match="disagree"):
        glmod.configure_gl(probe=probe)
    clean_gl_env.setenv("MUJOCO_GL", "glfw")
    clean_gl_env.delenv("PYOPENGL_PLATFORM")
    with pytest.raises(RendererUnavailableError, match="offscreen"):
        glmod.configure_gl(probe=probe)


def test_library_probe_on_this_machine():
    assert not glmod.library_loadable("libdefinitely-not-there.so.0")


def _render_depth_in_worker(renderer, T):
    return renderer.render(T, ("rgb", "depth"))


def test_a_pickled_renderer_renders_the_same_bytes_in_a_spawned_worker(room):
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    scene, poses = room
    renderer = make_renderer(scene, CAM, "mujoco")
    with ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn")) as pool:
        remote = pool.submit(_render_depth_in_worker, renderer, poses[2]).result(timeout=120)
    with renderer:
        local = renderer.render(poses[2], ("rgb", "depth"))
    assert remote.rgb.tobytes() == local.rgb.tobytes() and remote.depth.tobytes() == local.depth.tobytes()
