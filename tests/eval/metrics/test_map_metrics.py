"""The judge's map metrics with known answers: a model made of the scene's own surface samples, the same model
moved 10 cm, and one with every label wrong."""

from __future__ import annotations

import numpy as np
import pytest

from eval.metrics.map_metrics import MAP_METRICS, map_metrics
from sim_envs.agent import MapModel
from sim_envs.scenes.surface_sampling import sample_scene_surface
from sim_envs.sequences import get_sequence
from sim_envs.sources.simsource import SimulatedSequence


@pytest.fixture(scope="module")
def office():
    source = SimulatedSequence(get_sequence("office0").with_frames(30))
    frames = [source.frame(0), source.frame(29)]
    poses = np.stack([source.frame(i).T_world_cam for i in range(30)])
    surface = sample_scene_surface(source.scene, 0.02)
    yield source, frames, poses, surface
    source.close()


def test_the_scene_itself_is_a_perfect_map(office):
    source, frames, poses, surface = office
    model = MapModel(points=surface.points.astype(np.float32), labels=surface.labels)
    m = map_metrics(model, poses, poses, frames, source.intrinsics.as_array(), source.scene)
    assert set(m) == set(MAP_METRICS)
    assert m["map_accuracy_median"] < 1e-3 and m["map_accuracy_within"] == 1.0
    assert m["map_completeness_median"] < 1e-3 and m["map_completeness_within"] == 1.0
    assert m["map_label_accuracy"] == 1.0 and m["map_points"] == len(surface.points)


def test_a_shifted_model_and_wrong_labels_are_measured(office):
    source, frames, poses, surface = office
    shifted = MapModel(points=(surface.points + [0.0, 0.0, 0.10]).astype(np.float32),
                       labels=((surface.labels + 1) % 4).astype(np.uint8))
    # the estimate's poses moved with the model: the run's alignment takes the shift back out
    moved = poses.copy()
    moved[:, 2, 3] += 0.10
    m = map_metrics(shifted, poses, moved, frames, source.intrinsics.as_array(), source.scene)
    assert m["map_accuracy_median"] < 1e-3 and m["map_label_accuracy"] == 0.0
    # without that pose shift the model sits 10 cm off every horizontal surface (floor, table tops)
    off = map_metrics(shifted, poses, poses, frames, source.intrinsics.as_array(), source.scene)
    assert off["map_accuracy_within"] < m["map_accuracy_within"] and off["map_completeness_within"] < 1.0
