"""The room styles' data: every name it uses is a builder, and the test and training styles never meet."""

from sim_envs.scenes import furniture as fur
from sim_envs.scenes.room_styles import (
    OBJECTS_ON,
    RICH_FLOOR_TABLE,
    RICH_OBJECTS_ON,
    RICH_WALL_TABLE,
    ROOM_STYLES,
    SHELF_OBJECTS,
    STYLES,
    TEST_STYLES,
    TRAIN_STYLES,
    TUMBLING,
)


def test_styles_are_the_test_and_training_styles_and_disjoint() -> None:
    assert set(STYLES) == set(ROOM_STYLES) == set(TEST_STYLES) | set(TRAIN_STYLES)
    assert not set(TEST_STYLES) & set(TRAIN_STYLES)


def test_every_style_places_furniture_builders_with_valid_counts() -> None:
    for name, style in STYLES.items():
        assert style.name == name
        for item in style.items:
            assert item.builder in fur.FURNITURE, (name, item.builder)
            assert 0 <= item.count[0] <= item.count[1] and item.place in ("wall", "free"), (name, item)


def test_object_tables_name_object_and_decoration_builders() -> None:
    tables = [*OBJECTS_ON.values(), *RICH_OBJECTS_ON.values(), SHELF_OBJECTS, RICH_FLOOR_TABLE]
    for table in tables:
        for builder, weight in table:
            assert builder in fur.OBJECTS and weight > 0, builder
    assert all(builder in fur.WALL_DECORATIONS for builder, _ in RICH_WALL_TABLE)
    assert TUMBLING <= set(fur.OBJECTS)
