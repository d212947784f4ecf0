"""The room generator: determinism, styles, structure, non-overlapping furniture, texture density, rich rooms."""

import numpy as np
import pytest

from sim_envs.errors import SimEnvError, UnknownNameError
from sim_envs.frames import SemanticClass
from sim_envs.scenes.scenegen import ROOM_STYLES, TEST_STYLES, TRAIN_STYLES, generate_scene


@pytest.fixture(scope="module")
def office():
    return generate_scene("office", 0)


def _signature(scene):
    """Everything that defines a scene, as comparable numbers and bytes."""
    poses = np.stack([p.T_world_obj for p in scene.primitives])
    sizes = np.array([p.size for p in scene.primitives])
    names = [p.name for p in scene.primitives]
    textures = [m.texture.tobytes() if m.texture is not None else m.rgb for m in scene.materials()]
    return poses, sizes, names, textures


def test_same_seed_gives_the_same_scene(office):
    again = generate_scene("office", 0)
    a, b = _signature(office), _signature(again)
    np.testing.assert_array_equal(a[0], b[0])
    np.testing.assert_array_equal(a[1], b[1])
    assert a[2] == b[2] and a[3] == b[3]
    np.testing.assert_array_equal(office.room_size, again.room_size)
    assert office.lights == again.lights and office.ambient == again.ambient


def test_other_seed_or_style_gives_another_scene(office):
    other = generate_scene("office", 1)
    assert not np.array_equal(office.room_size, other.room_size)
    living = generate_scene("living", 0)
    assert not np.array_equal(office.room_size, living.room_size)


def test_style_lists():
    assert TEST_STYLES == ("office", "living")
    assert len(TRAIN_STYLES) >= 3 and not set(TRAIN_STYLES) & set(TEST_STYLES)
    assert set(ROOM_STYLES) == set(TEST_STYLES) | set(TRAIN_STYLES)


def test_unknown_style_lists_valid_ones():
    with pytest.raises(UnknownNameError) as err:
        generate_scene("castle", 0)
    for style in ROOM_STYLES:
        assert style in str(err.value)
    with pytest.raises(SimEnvError, match="texture_density"):
        generate_scene("office", 0, texture_density=1.5)


@pytest.mark.parametrize("style", ROOM_STYLES)
def test_every_style_has_structure_furniture_and_objects(style):
    scene = generate_scene(style, 3, settle=False)
    kinds = {p.instance_kind for p in scene.primitives}
    assert {"floor", "ceiling", "wall", "door", "window"} <= kinds
    classes = set(scene.instance_classes().tolist())
    assert classes == {int(c) for c in SemanticClass}
    names = scene.instance_names()
    assert sum(n.startswith("wall_") for n in names) == 4
    Lx, Ly, H = scene.room_size
    assert 3.0 <= Lx <= 8.0 and 3.0 <= Ly <= 8.0 and 2.3 <= H <= 3.3
    # furniture and objects stay inside the room
    boxes = scene.instance_aabbs()[scene.instance_classes() >= SemanticClass.LARGE_STRUCTURE]
    assert (boxes[:, 0] >= [-0.01, -0.01, -0.01]).all() and (boxes[:, 1] <= scene.room_size + 0.01).all()


@pytest.mark.parametrize("style", TEST_STYLES)
def test_test_styles_are_rooms_like_icl_nuim(style):
    for seed in range(3):
        Lx, Ly, H = generate_scene(style, seed, settle=False).room_size
        assert 4.0 <= Lx <= 6.0 and 4.0 <= Ly <= 6.0 and 2.5 <= H <= 2.8


def _boxes(prim):
    """(centre (3,), axes (3, 3) columns, half sizes (3,)) of a primitive's oriented bounding box."""
    T = prim.T_world_obj
    r = prim.size[0]
    half = {"box": np.array(prim.size), "cylinder": np.array([r, r, prim.size[1]]), "sphere": np.full(3, r)}[prim.kind]
    return T[:3, 3], T[:3, :3], half


def _obb_overlap(a, b, tol):
    """Separating-axis test of two oriented boxes, each shrunk by ``tol`` metres (touching is not overlapping)."""
    (ca, Ra, ha), (cb, Rb, hb) = a, b
    ha, hb = np.maximum(ha - tol, 0), np.maximum(hb - tol, 0)
    axes = [Ra[:, i] for i in range(3)] + [Rb[:, i] for i in range(3)]
    axes += [np.cross(Ra[:, i], Rb[:, j]) for i in range(3) for j in range(3)]
    d = cb - ca
    for axis in axes:
        n = np.linalg.norm(axis)
        if n < 1e-9:
            continue
        axis = axis / n
        ra = np.abs(Ra.T @ axis) @ ha
        rb = np.abs(Rb.T @ axis) @ hb
        if abs(d @ axis) > ra + rb:
            return False
    return True


@pytest.mark.parametrize("style,seed", [("office", 0), ("living", 0), ("classroom", 1), ("kitchen", 2)])
def test_furniture_does_not_intersect_furniture_or_structure(style, seed):
    scene = generate_scene(style, seed, settle=False)
    large = [p for p in scene.primitives if p.semantic == SemanticClass.LARGE_STRUCTURE]
    structure = [p for p in scene.primitives if p.semantic == SemanticClass.VERTICAL_STRUCTURE]
    boxes = np.array([p.aabb() for p in large + structure])
    # candidate pairs by axis-aligned bounds first, then the exact oriented test
    near = ((boxes[:, None, 0] < boxes[None, :, 1]) & (boxes[None, :, 0] < boxes[:, None, 1])).all(2)
    clashes = []
    for i, j in zip(*np.nonzero(np.triu(near[: len(large)], 1)), strict=True):
        p, q = large[i], (large + structure)[j]
        if p.instance != q.instance and _obb_overlap(_boxes(p), _boxes(q), tol=0.002):
            clashes.append((p.name, q.name))
    assert not clashes


def test_overlap_check_itself():
    unit = (np.zeros(3), np.eye(3), np.ones(3))
    c, s = np.cos(np.pi / 4), np.sin(np.pi / 4)
    turned = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    assert _obb_overlap(unit, (np.array([1.9, 0, 0]), np.eye(3), np.ones(3)), 0.002)
    assert not _obb_overlap(unit, (np.array([2.0, 0, 0]), np.eye(3), np.ones(3)), 0.002)
    assert _obb_overlap(unit, (np.array([2.3, 0, 0]), turned, np.ones(3)), 0.002)  # corner reaches x = 0.886
    assert not _obb_overlap(unit, (np.array([2.5, 0, 0]), turned, np.ones(3)), 0.002)


def test_texture_density_changes_textures_not_layout(office):
    plain = generate_scene("office", 0, texture_density=0.0)
    half = generate_scene("office", 0, texture_density=0.5)
    np.testing.assert_array_equal(_signature(plain)[0], _signature(office)[0])
    assert all(m.texture is None for m in plain.materials())
    n_full = sum(m.texture is not None for m in office.materials())
    n_half = sum(m.texture is not None for m in half.materials())
    assert n_full > n_half > 0

    def contrast(scene):
        return np.mean([m.texture.std() for m in scene.materials() if m.texture is not None])

    assert contrast(half) < contrast(office)


def test_lights_never_saturate(office):
    assert office.ambient + sum(light.intensity for light in office.lights) <= 1.0
    for light in office.lights:
        assert np.linalg.norm(light.direction) == pytest.approx(1.0) and light.direction[2] < 0


def test_camera_space_helpers_on_a_generated_room(office):
    pts = office.interest_points()
    assert len(pts) >= 10
    assert (pts >= -0.01).all() and (pts <= office.room_size + 0.01).all()
    rng = np.random.default_rng(0)
    candidates = rng.uniform([0, 0, 0], office.room_size, (2000, 3))
    free = office.free_space(candidates, margin=0.3)
    assert 0.05 < free.mean() < 0.95
    boxes = office.instance_aabbs()[office.instance_classes() >= SemanticClass.LARGE_STRUCTURE]
    inside_any = ((candidates[free, None] >= boxes[None, :, 0]) & (candidates[free, None] <= boxes[None, :, 1])).all(2)
    assert not inside_any.any()


# ------------------------------------------------------------------------------------------------------ rich rooms
@pytest.fixture(scope="module")
def rich():
    return generate_scene("office", 0, detail="rich")


def test_a_rich_room_is_the_standard_room_with_more(office, rich):
    assert rich.detail == "rich" and office.detail == "standard"
    np.testing.assert_array_equal(rich.room_size, office.room_size)
    assert rich.lights == office.lights and rich.ambient == office.ambient
    # the same furniture and structure, at the same poses (only small objects are settled again, among more)
    kinds = {"floor", "ceiling", "wall", "door", "window", "desk", "chair", "bookshelf", "cabinet", "table", "poster"}
    same = [(p.name, p.T_world_obj.tobytes()) for p in office.primitives if p.instance_kind in kinds]
    assert same == [(p.name, p.T_world_obj.tobytes()) for p in rich.primitives if p.instance_kind in kinds]
    assert rich.n_instances > office.n_instances + 30  # clutter, floor objects, wall decorations
    new = {p.instance_kind for p in rich.primitives} - {p.instance_kind for p in office.primitives}
    assert {"frame", "tin", "carton"} <= new


def test_rich_room_texture_energy_and_determinism(office, rich):
    def energy(scene):  # mean absolute horizontal step of the textures, per material
        return np.mean([np.abs(np.diff(m.texture.astype(np.float32), axis=1)).mean() if m.texture is not None else 0.0
                        for m in scene.materials()])  # fmt: skip

    assert energy(rich) > 1.5 * energy(office)
    assert all(m.texture is not None for m in rich.materials())  # plain colours get detail too
    again = generate_scene("office", 0, detail="rich")
    a, b = _signature(rich), _signature(again)
    np.testing.assert_array_equal(a[0], b[0])
    assert a[2] == b[2] and a[3] == b[3]


def test_rich_wall_decorations_hang_flat_on_the_walls(rich):
    boxes, names = rich.instance_aabbs(), rich.instance_names()
    hung = 0
    for box, name in zip(boxes, names, strict=True):
        if name.rsplit("_", 1)[0] in ("frame", "pinboard", "clock", "calendar", "switch"):
            hung += 1
            assert np.minimum(box[1, :2], rich.room_size[:2] - box[0, :2]).min() < 0.06, name  # <= 5 cm out
            assert 0.7 < box[0, 2] and box[1, 2] < rich.room_size[2] - 0.1, name
    assert hung >= 10


def test_rich_room_at_density_zero_keeps_plain_colours():
    plain = generate_scene("living", 3, texture_density=0.0, detail="rich")
    assert all(m.texture is None for m in plain.materials())
    with pytest.raises(SimEnvError, match="detail must be one of standard, rich"):
        generate_scene("office", 0, detail="cluttered")
