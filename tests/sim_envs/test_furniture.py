"""Furniture and small objects: the one-primitive helpers, the variants, and every registered builder's assembly."""

import numpy as np
import pytest

from sim_envs.scenes import furniture as fur
from sim_envs.scenes.materials import MaterialBank
from sim_envs.scenes.scene import Material

ALL_BUILDERS = {**fur.FURNITURE, **fur.OBJECTS, **fur.WALL_DECORATIONS}


def _bank(seed: int = 0) -> MaterialBank:
    return MaterialBank(np.random.default_rng(seed), 1.0)


def test_solid_box_stands_on_its_bottom() -> None:
    a = fur._solid_box("carton", 0.1, 0.05, 0.2, Material("m"))
    assert a.half == (0.1, 0.05) and a.height == pytest.approx(0.4) and a.semantic == fur.SMALL
    (part,) = a.parts
    assert part.kind == "box" and part.name == "body" and part.size == (0.1, 0.05, 0.2)
    np.testing.assert_allclose(fur.part_corners(part)[:, 2].min(), 0.0, atol=1e-12)


def test_solid_cylinder_stands_on_its_bottom() -> None:
    a = fur._solid_cylinder("tin", 0.05, 0.3, Material("m"))
    (part,) = a.parts
    assert a.half == (0.05, 0.05) and a.height == 0.3 and part.kind == "cylinder" and part.size == (0.05, 0.15, 0.0)
    np.testing.assert_allclose(part.T[:3, 3], [0.0, 0.0, 0.15])


@pytest.mark.parametrize(("variant", "base", "options"), [
    (fur.small_desk, fur.desk, {"small": True}), (fur.coffee_table, fur.table, {"coffee": True}),
    (fur.armchair, fur.sofa, {"seats": 1}), (fur.wardrobe, fur.cabinet, {"tall": True}),
    (fur.teacher_desk, fur.desk, {}), (fur.tv, fur.monitor, {"tv": True}),
    (fur.large_plant, fur.plant, {"large": True}),
])  # fmt: skip
def test_a_variant_is_its_base_with_fixed_options(variant, base, options) -> None:
    a = variant(np.random.default_rng(4), _bank())
    b = base(np.random.default_rng(4), _bank(), **options)
    assert a.kind == b.kind and [p.name for p in a.parts] == [p.name for p in b.parts]
    for p, q in zip(a.parts, b.parts, strict=True):
        assert p.size == q.size and np.array_equal(p.T, q.T)
    assert variant.__doc__ and variant.__name__ != base.__name__


@pytest.mark.parametrize("name", sorted({**fur.FURNITURE, **fur.OBJECTS}))
def test_every_fitted_builder_is_bounded_by_its_footprint_and_height(name: str) -> None:
    for seed in range(3):
        a = {**fur.FURNITURE, **fur.OBJECTS}[name](np.random.default_rng(seed), _bank(seed))
        corners = np.concatenate([fur.part_corners(p) for p in a.parts])
        assert a.parts and np.all(np.abs(corners[:, :2]) <= np.asarray(a.half) + 1e-9), name
        assert corners[:, 2].max() <= a.height + 1e-9 and corners[:, 2].min() >= -1e-9, name


def test_builders_are_deterministic_per_seed() -> None:
    for name, build in ALL_BUILDERS.items():
        a, b = build(np.random.default_rng(7), _bank(7)), build(np.random.default_rng(7), _bank(7))
        assert [(p.name, p.size) for p in a.parts] == [(p.name, p.size) for p in b.parts], name
        assert all(np.array_equal(p.T, q.T) for p, q in zip(a.parts, b.parts, strict=True)), name
