"""What a run gives its method (the method table's ``input``): the suite's frames, or a real folder's own size and
raw images with the lens distortion handed to the agent; and the run record says which (``metadata.method_input``).
"""

from __future__ import annotations

import importlib
import json
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

from eval.bench.methods import Method, MethodError, parse_methods
from eval.bench.run import RunSpec, execute_run
from eval.bench.sequence_ref import SequenceRef
from sim_envs.camera import preset
from sim_envs.folders.datasets import RgbdFolder
from sim_envs.folders.folder_exports import write_folder
from sim_envs.frames import Frame

AGENTS = '''
import numpy as np

class Recording:
    """Records what reset and the first step were given (class attributes, read back by the test)."""
    calls = []
    name = "recording"

    def reset(self, *args, **kwargs):
        Recording.calls.append({"args": args, "kwargs": kwargs, "images": []})

    def step(self, observation):
        Recording.calls[-1]["images"].append(observation["rgb"].copy())
        return {"T_world_cam": np.eye(4), "tracked": 1}

    def finish(self):
        return {"extras": {}}


class RecordingUndistorter(Recording):
    takes_distortion = True
'''


class TexturedSource:
    """A few frames of a fixed random texture (seeded) at ``width`` x ``height``, the camera moving along x."""

    def __init__(self, width: int, height: int, n: int = 4) -> None:
        self.name = "textured"
        self.intrinsics = preset("tum_fr1", width, height)
        self.timestamps = 10.0 + np.arange(n) / 30.0
        self.poses = np.tile(np.eye(4), (n, 1, 1))
        self.poses[:, 0, 3] = 0.01 * np.arange(n)
        texture = np.random.default_rng(3).integers(0, 256, (height // 4, width // 4, 3), dtype=np.uint8)
        self._rgb = cv2.resize(texture, (width, height), interpolation=cv2.INTER_NEAREST)

    def __len__(self) -> int:
        return len(self.timestamps)

    def frame(self, index: int) -> Frame:
        shape = self._rgb.shape[:2]
        return Frame(index, float(self.timestamps[index]), np.roll(self._rgb, index, axis=1),
                     np.full(shape, 2.0, np.float32), self.poses[index].copy())

    def close(self) -> None:
        pass


def distorted_tum_folder(root: Path, width: int = 64, height: int = 48) -> Path:
    """A TUM folder named as fr1 (so its camera is TUM's fr1, with its lens distortion, scaled to the images)."""
    folder = root / "rgbd_dataset_freiburg1_tiny"
    write_folder(TexturedSource(width, height), folder, "tum", camera_file=False)
    return folder


@pytest.fixture
def agents(tmp_path, monkeypatch):
    (tmp_path / "given_agents.py").write_text(AGENTS)
    monkeypatch.syspath_prepend(str(tmp_path))
    sys.modules.pop("given_agents", None)
    module = importlib.import_module("given_agents")
    module.Recording.calls.clear()
    yield module
    sys.modules.pop("given_agents", None)


def _run(folder: Path, method: Method) -> dict:
    spec = RunSpec("t", SequenceRef(folder.name, folder=str(folder)), method, frames=3, plots=False,
                   known_fingerprint="test")
    result = execute_run(spec)
    assert result.status == "done", result.traceback
    return json.loads(result.files["metrics.json"])["metadata"]


def test_native_input_gives_raw_images_and_the_distortion(tmp_path, agents):
    folder = distorted_tum_folder(tmp_path)
    native = Method("undistorts-itself", entry_point="given_agents:RecordingUndistorter", metrics=("trajectory",),
                    input="native")
    given = _run(folder, native)["method_input"]
    call = agents.Recording.calls[-1]
    raw = RgbdFolder(folder, size=None, undistort="none")
    assert raw.camera.distorted
    (K, size), distortion = call["args"], call["kwargs"]["distortion"]
    assert size == (48, 64) and np.allclose(K, preset("tum_fr1", 64, 48).as_array())
    np.testing.assert_array_equal(distortion, raw.camera.distortion)  # fr1's k1 k2 p1 p2 k3
    for i, image in enumerate(call["images"]):  # the images as on disk, not undistorted, not resized
        np.testing.assert_array_equal(image, cv2.cvtColor(cv2.imread(str(raw.rgb_paths[i])), cv2.COLOR_BGR2RGB))
    assert given["input"] == "native" and given["undistortion"] == "method"
    assert given["image_size"] == {"width": 64, "height": 48}
    assert list(given["distortion"].values()) == pytest.approx(list(raw.camera.distortion))
    assert given["intrinsics"]["fx"] == pytest.approx(preset("tum_fr1", 64, 48).fx)


def test_harness_input_is_as_before(tmp_path, agents):
    """The default: the folder undistorted by the harness and resized to 320x240, reset(intrinsics, image_size)
    with nothing more, even for an agent that would take the distortion; the images' bytes those of the reader."""
    folder = distorted_tum_folder(tmp_path)
    before = RgbdFolder(folder, size=(320, 240))  # what every method was given before the method table's input
    for entry in ("Recording", "RecordingUndistorter"):
        given = _run(folder, Method(entry, entry_point=f"given_agents:{entry}", metrics=("trajectory",)))
        call = agents.Recording.calls[-1]
        assert len(call["args"]) == 2 and (entry == "Recording") == (call["kwargs"] == {})
        assert call["args"][1] == (240, 320) and np.array_equal(call["args"][0], before.intrinsics.as_array())
        if call["kwargs"]:  # an agent that takes the distortion is told the undistorted images have none
            assert not np.any(call["kwargs"]["distortion"])
        for i, image in enumerate(call["images"]):
            np.testing.assert_array_equal(image, before.frame(i).rgb)
        record = given["method_input"]
        assert record["input"] == "harness" and record["undistortion"] == "harness"
        assert record["image_size"] == {"width": 320, "height": 240} and not any(record["distortion"].values())


def test_a_pinhole_folder_is_not_undistorted_by_anyone(tmp_path, agents):
    folder = tmp_path / "pinhole"
    write_folder(TexturedSource(64, 48), folder, "tum")  # camera.toml: the source's pinhole intrinsics
    given = _run(folder, Method("n", entry_point="given_agents:RecordingUndistorter", metrics=("trajectory",),
                                input="native"))["method_input"]
    assert given["undistortion"] == "none" and given["image_size"] == {"width": 64, "height": 48}
    assert not np.any(agents.Recording.calls[-1]["kwargs"]["distortion"])


def test_native_input_for_an_agent_that_takes_no_distortion_fails_the_run(tmp_path, agents):
    folder = distorted_tum_folder(tmp_path)
    spec = RunSpec("t", SequenceRef(folder.name, folder=str(folder)),
                   Method("n", entry_point="given_agents:Recording", metrics=("trajectory",), input="native"),
                   frames=2, plots=False, known_fingerprint="test")
    result = execute_run(spec)
    assert result.status == "failed" and "takes_distortion" in (result.error or "")
    assert agents.Recording.calls == []  # refused before the episode


def test_the_record_lists_the_input_files(tmp_path, agents):
    weights = tmp_path / "weights.bin"
    weights.write_bytes(b"x" * 123)
    folder = distorted_tum_folder(tmp_path)
    given = _run(folder, Method("w", entry_point="given_agents:Recording", metrics=("trajectory",),
                                inputs=(str(weights),)))["method_input"]
    assert given["files"] == {str(weights): {"file": "weights.bin", "bytes": 123}}


def test_a_bad_input_value_is_refused_when_the_table_is_read():
    table = {"methods": {"M": {"entry_point": "a:B", "input": "raw"}}}
    with pytest.raises(MethodError, match=r"<t>: method 'M': input must be one of harness, native .*got 'raw'"):
        parse_methods(table, "<t>")
    with pytest.raises(MethodError, match=r"methods.M.input = 3; input is a string"):
        parse_methods({"methods": {"M": {"entry_point": "a:B", "input": 3}}}, "<t>")
    assert parse_methods({"methods": {"M": {"entry_point": "a:B", "input": "native"}}})["M"].input == "native"


def test_the_default_input_leaves_a_method_definition_as_it_was():
    assert "input" not in Method("m", entry_point="a:B").describe()  # its runs' fingerprints unchanged
    assert Method("m", entry_point="a:B", input="native").describe()["input"] == "native"
    ref = SequenceRef("s", folder="/nowhere")
    assert Method("m", entry_point="a:B").given_sequence(ref) is ref
    native = Method("m", entry_point="a:B", input="native").given_sequence(ref)
    assert (native.name, native.size, native.undistort) == ("s", "native", "none")
    office = SequenceRef("office0", base="office0")  # a simulated sequence: rendered at its own size either way
    assert Method("m", entry_point="a:B", input="native").given_sequence(office) is office
