"""The camera's stages: the chain's order, presets as ordered stage lists, each stage checking its own parameters, and a
new effect as one class: defined in a test (or added to sim_envs/sensor/camera_stages.py in a copy of the tree), it is a
single effect by name, a camera the sequences render through, and one of the sweep's camera axes, with no other file
edited."""

import dataclasses
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from sim_envs.camera import Intrinsics
from sim_envs.errors import SimEnvError, UnknownNameError
from sim_envs.sensor import camera_stages
from sim_envs.sensor.camera_effects import (
    SINGLE_EFFECTS,
    CameraEffects,
    camera_effects_preset,
    decode_render,
    encode,
    sensor_image,
    single_effect,
)
from sim_envs.sensor.camera_stages import (
    BUILTIN_STAGES,
    EFFECT_STAGES,
    PRESET_STAGES,
    AutoExposure,
    CameraStage,
    Exposure,
    FrameContext,
    MotionBlur,
    Noise,
    Response,
    RollingShutter,
)

W, H = 32, 24
K = Intrinsics(30.0, 30.0, 15.5, 11.5, W, H)
REPO = Path(__file__).resolve().parents[2]


def _render(T: np.ndarray) -> np.ndarray:
    """(H, W, 3) uint8 gradient, no OpenGL."""
    u, v = np.meshgrid(np.arange(W), np.arange(H))
    return np.stack([4 * u + 20, 6 * v + 10, np.full_like(u, 90)], axis=-1).astype(np.uint8)


def _pose_at(times: np.ndarray) -> np.ndarray:
    return np.tile(np.eye(4), (len(times), 1, 1))


def test_the_chain_is_in_image_formation_order():
    names = [type(s).__name__ for s in camera_effects_preset("hard").stages]
    assert names == ["Distortion", "MotionBlur", "RollingShutter", "Exposure", "Vignetting", "FullWell", "Noise",
                     "AutoExposure", "Response", "SensorDepth"]  # fmt: skip
    assert [c.__name__ for c in BUILTIN_STAGES] == names
    for cls in BUILTIN_STAGES:  # the built-in stages' parameters are CameraEffects fields of the same names
        assert {f.name for f in dataclasses.fields(cls)} <= {f.name for f in dataclasses.fields(CameraEffects)}
    assert list(EFFECT_STAGES) == ["noise", "blur", "exposure", "rolling_shutter", "distortion"]
    assert list(SINGLE_EFFECTS) == list(EFFECT_STAGES) and "glare" not in SINGLE_EFFECTS


def test_a_preset_is_its_ordered_stage_list():
    for name, stages in PRESET_STAGES.items():
        fx = camera_effects_preset(name)
        assert fx == CameraEffects.from_stages(name, stages) and fx.name == name
        for stage in stages:  # each listed stage is the camera's stage of its class
            assert fx.stage(type(stage)) == stage
        assert [s.order for s in stages] == sorted(s.order for s in stages)  # listed in chain order
    kinect = camera_effects_preset("kinect")
    assert kinect.stage(Noise).sensor_width == 640 and kinect.stage(MotionBlur).blur_subframes == 3
    assert not camera_effects_preset("clean").any and CameraEffects.from_stages("clean", ()) == CameraEffects("clean")
    with pytest.raises(SimEnvError, match="Noise given twice"):
        CameraEffects.from_stages("twice", (Noise(), Noise()))
    with pytest.raises(SimEnvError, match="extra_stages takes camera stages other than the built-in"):
        CameraEffects(extra_stages=(Noise(),))


@pytest.mark.parametrize("cls, values, message", [
    (Noise, {"shot_noise": (1.0, 2.0)}, "shot_noise must be 3 numbers"),
    (MotionBlur, {"blur_subframes": 0}, "blur_subframes must be an integer >= 1"),
    (RollingShutter, {"readout_s": -1.0}, "readout_s must be >= 0"),
    (Exposure, {"scene_light": 0.0}, "scene_light must be a number > 0"),
    (AutoExposure, {"ae_min_s": 0.1, "ae_max_s": 0.01}, r"ae_min_s \(0.1\) must not exceed ae_max_s"),
    (Response, {"response": "log"}, "unknown response 'log'; valid: srgb, gamma"),
])  # fmt: skip
def test_each_stage_checks_its_own_parameters(cls, values, message):
    with pytest.raises(SimEnvError, match=message):
        cls(**values)
    with pytest.raises(SimEnvError, match=message):  # the configuration's fields go through the same check
        CameraEffects(**values)


def test_stage_hooks_known_answers():
    x = np.full((2, 2, 3), 0.5, np.float32)
    frame = FrameContext(exposure_s=0.02, gain=3.0)
    assert Exposure(reference_exposure_s=0.01).signal(x.copy(), frame)[0, 0, 0] == np.float32(1.0)
    assert AutoExposure().signal(x.copy(), frame)[0, 0, 0] == np.float32(1.5)
    assert Noise().signal(x, frame) is x  # no noise: no draw, the same array
    assert MotionBlur(blur_subframes=5).times(0.0, 0.02, H).tolist() == pytest.approx([-0.01, -0.005, 0, 0.005, 0.01])
    assert MotionBlur().times(0.5, 0.02, H).tolist() == [0.0]  # one render: no window
    assert Response().inverse()[[0, 255]].tolist() == [0.0, 255.0]


class _Gain:
    """The body of a new effect stage: the linear signal times 1 + s (after the noise, before the analogue gain)."""

    @staticmethod
    def define() -> type[CameraStage]:
        @dataclasses.dataclass(frozen=True)
        class Gain(CameraStage):
            """The linear sensor signal times ``factor``."""

            factor: float = 1.0

            order = 65.0
            effect = "gain"
            strength = "the linear signal times 1 + s"
            axis_title = "gain alone, 1 + s"
            sweep_strengths = (0.5, 1.0)

            @classmethod
            def alone(cls, s: float) -> tuple[CameraStage, ...]:
                return (cls(factor=1.0 + s),)

            def signal(self, x: np.ndarray, frame: FrameContext) -> np.ndarray:
                x *= np.float32(self.factor)
                return x

        return Gain


def test_a_new_effect_is_one_class(monkeypatch):
    from eval.bench.suites import CAMERA_EFFECT_STRENGTHS, SWEEP_AXES, sweep_sequences

    axes_before = list(SWEEP_AXES)
    with monkeypatch.context() as m:
        m.setattr(camera_stages, "EFFECT_STAGES", dict(EFFECT_STAGES))  # the class registers in a copy
        Gain = _Gain.define()
        assert SINGLE_EFFECTS["gain"] == "the linear signal times 1 + s"
        fx = camera_effects_preset("gain:1")
        assert fx == single_effect("gain", 1.0) and fx.name == "gain:1" and fx.extra_stages == (Gain(factor=2.0),)
        assert fx.any and fx.photometric and fx.describe()["extra_stages"] == [{"stage": "Gain", "factor": 2.0}]
        assert not single_effect("gain", 0).any
        img = sensor_image(_render, _pose_at, 0.0, fx, K, np.random.default_rng(0))
        np.testing.assert_array_equal(img, encode(decode_render(_render(np.eye(4))) * np.float32(2.0),
                                                  CameraEffects()))  # fmt: skip
        # the sweep's axes and sequences come from the stage classes
        assert list(SWEEP_AXES) == [*axes_before, "gain"] and SWEEP_AXES["gain"] == "gain alone, 1 + s"
        assert CAMERA_EFFECT_STRENGTHS["gain"] == (0.5, 1.0)
        refs = [r for r in sweep_sequences() if r.axis == "gain"]
        assert [(r.name, r.axis_value) for r in refs] == [("office1@gain0.5", 0.5), ("office1@gain1", 1.0)]
        assert refs[1].spec().camera_effects_model() == fx
    assert "gain" not in SINGLE_EFFECTS and list(SWEEP_AXES) == axes_before  # the registry is back
    with pytest.raises(UnknownNameError, match="EFFECT one of noise, blur, exposure, rolling_shutter, distortion$"):
        camera_effects_preset("gain:1")


@pytest.mark.slow
def test_a_sequence_renders_through_a_new_effect(monkeypatch):
    from sim_envs.sequences import get_sequence, with_camera
    from sim_envs.sources.simsource import SimulatedSequence

    monkeypatch.setattr(camera_stages, "EFFECT_STAGES", dict(EFFECT_STAGES))
    _Gain.define()
    base = dataclasses.replace(get_sequence("office0").with_frames(2), width=W, height=H)
    with SimulatedSequence(with_camera(base, "gain:1")) as seq, SimulatedSequence(base) as clean:
        np.testing.assert_array_equal(seq.rgb(1), encode(decode_render(clean.rgb(1)) * np.float32(2.0),
                                                         CameraEffects()))  # fmt: skip


def test_an_effect_name_is_defined_once(monkeypatch):
    monkeypatch.setattr(camera_stages, "EFFECT_STAGES", dict(EFFECT_STAGES))
    with pytest.raises(SimEnvError, match="camera effect 'noise' is defined twice"):
        type("OtherNoise", (CameraStage,), {"effect": "noise"})


_GAIN_SOURCE = '''

@dataclass(frozen=True)
class Gain(CameraStage):
    """The linear sensor signal times ``factor``."""

    factor: float = 1.0

    order: ClassVar[float] = 65.0
    effect: ClassVar[str | None] = "gain"
    strength: ClassVar[str] = "the linear signal times 1 + s"
    axis_title: ClassVar[str] = "gain alone, 1 + s"
    sweep_strengths: ClassVar[tuple[float, ...]] = (0.5, 1.0)

    @classmethod
    def alone(cls, s: float) -> tuple[CameraStage, ...]:
        return (cls(factor=1.0 + s),)

    def signal(self, x: np.ndarray, frame: FrameContext) -> np.ndarray:
        x *= np.float32(self.factor)
        return x
'''
_CHECK = """
from eval.bench.suites import SWEEP_AXES, sweep_sequences
from sim_envs.sensor.camera_effects import camera_effects_preset, single_effect
assert single_effect("gain", 1).extra_stages[0].factor == 2.0
assert camera_effects_preset("gain:0.5").any
assert SWEEP_AXES["gain"] == "gain alone, 1 + s"
assert [r.name for r in sweep_sequences() if r.axis == "gain"] == ["office1@gain0.5", "office1@gain1"]
print("ok")
"""


def test_a_new_effect_in_a_copy_of_the_tree_touches_one_file(tmp_path):
    skip = shutil.ignore_patterns("__pycache__", "*.pyc")
    for package in ("sim_envs", "eval", "slamcommon"):
        shutil.copytree(REPO / package, tmp_path / package, ignore=skip)
    stages = tmp_path / "sim_envs" / "sensor" / "camera_stages.py"
    stages.write_text(stages.read_text() + _GAIN_SOURCE)
    changed = [p.relative_to(tmp_path).as_posix() for p in tmp_path.rglob("*.py")
               if p.read_bytes() != (REPO / p.relative_to(tmp_path)).read_bytes()]  # fmt: skip
    assert changed == ["sim_envs/sensor/camera_stages.py"]
    run = subprocess.run([sys.executable, "-c", _CHECK], cwd=tmp_path, capture_output=True, text=True, timeout=120,
                         env={"PYTHONPATH": str(tmp_path), "PATH": "/usr/bin:/bin"})  # fmt: skip
    assert run.returncode == 0 and run.stdout.strip() == "ok", run.stderr[-2000:]


def test_an_effect_without_alone_is_refused_where_it_is_defined():
    """A stage named as a single effect must say how it stands alone: refused when its class is defined, not when a
    sweep first asks for it."""
    import dataclasses

    import pytest

    from sim_envs.errors import SimEnvError
    from sim_envs.sensor.camera_stages import EFFECT_STAGES, CameraStage

    with pytest.raises(SimEnvError, match="'lonely'.*defines no alone"):
        @dataclasses.dataclass(frozen=True)
        class Lonely(CameraStage):
            effect = "lonely"
    assert "lonely" not in EFFECT_STAGES
    with pytest.raises(SimEnvError, match="is not a single effect"):
        CameraStage.alone(1.0)
