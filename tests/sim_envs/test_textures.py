"""Procedural textures: shapes, determinism, seamless tiling, low-texture paint, contrast scaling, material bank."""

import numpy as np
import pytest

from sim_envs.scenes import textures
from sim_envs.scenes.materials import SLOTS, MaterialBank

TILING = [textures.wood, textures.planks, textures.carpet, textures.tiles, textures.wallpaper, textures.fabric,
          textures.paint, textures.concrete]  # fmt: skip
SINGLE = [textures.poster, textures.book_cover, textures.screen, textures.window_view, textures.whiteboard,
          textures.door_panel, textures.page, textures.clock_face]  # fmt: skip


@pytest.mark.parametrize("fn", TILING + SINGLE, ids=lambda f: f.__name__)
def test_textures_are_uint8_rgb_and_deterministic(fn):
    a = fn(np.random.default_rng(7))
    b = fn(np.random.default_rng(7))
    c = fn(np.random.default_rng(8))
    assert a.dtype == np.uint8 and a.ndim == 3 and a.shape[2] == 3 and min(a.shape[:2]) >= 32
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)


@pytest.mark.parametrize("fn", TILING, ids=lambda f: f.__name__)
def test_repeating_textures_tile_without_seams(fn):
    img = fn(np.random.default_rng(3)).astype(np.float64)
    # the jump across the wrap-around seam is no larger than between neighbouring columns / rows inside the image
    inside_x = np.abs(np.diff(img, axis=1)).mean()
    inside_y = np.abs(np.diff(img, axis=0)).mean()
    seam_x = np.abs(img[:, 0] - img[:, -1]).mean()
    seam_y = np.abs(img[0] - img[-1]).mean()
    assert seam_x <= 2.5 * inside_x + 1.0
    assert seam_y <= 2.5 * inside_y + 1.0


def test_noise_is_periodic_exactly():
    n = textures.periodic_noise(np.random.default_rng(0), 64, 8)
    big = np.tile(n, (2, 2))
    # a period-shifted copy equals itself: no discontinuity larger than the largest interior step
    assert np.abs(np.diff(big, axis=1)).max() <= np.abs(np.diff(n, axis=1)).max() + 1e-6


def test_paint_is_low_texture_and_wood_is_not():
    rng = np.random.default_rng(0)
    paint, wood = textures.paint(rng), textures.wood(rng)
    assert paint.std(axis=(0, 1)).max() < 3.0
    assert wood.std(axis=(0, 1)).max() > 15.0


def test_scale_contrast():
    img = textures.carpet(np.random.default_rng(1))
    flat = textures.scale_contrast(img, 0.0)
    assert flat.std(axis=(0, 1)).max() < 0.6
    np.testing.assert_allclose(flat.reshape(-1, 3).mean(0), img.reshape(-1, 3).mean(0), atol=1.0)
    half = textures.scale_contrast(img, 0.5)
    np.testing.assert_allclose(half.std(axis=(0, 1)), img.std(axis=(0, 1)) / 2, rtol=0.05)
    assert textures.scale_contrast(img, 1.0) is img


def test_detailed_raises_contrast_adds_wear_and_keeps_tiling():
    paint = textures.paint(np.random.default_rng(2))
    rich = textures.detailed(paint, np.random.default_rng(5), 2.0, 0.15, 0.25, 0.04)
    np.testing.assert_array_equal(rich, textures.detailed(paint, np.random.default_rng(5), 2.0, 0.15, 0.25, 0.04))
    assert rich.shape == paint.shape and rich.dtype == np.uint8
    assert rich.std(axis=(0, 1)).min() > 3 * paint.std(axis=(0, 1)).max()  # wear at several scales on plain paint
    np.testing.assert_allclose(rich.reshape(-1, 3).mean(0), paint.reshape(-1, 3).mean(0), rtol=0.08)
    img = rich.astype(np.float64)  # still tiles: the seam is no rougher than the inside
    assert np.abs(img[:, 0] - img[:, -1]).mean() <= 2.5 * np.abs(np.diff(img, axis=1)).mean() + 1.0
    wood = textures.wood(np.random.default_rng(1))
    contrast = textures.detailed(wood, np.random.default_rng(0), 2.0, 0.0, 0.0)
    np.testing.assert_allclose(contrast.std(axis=(0, 1)), 2 * wood.std(axis=(0, 1)), rtol=0.02)
    gain = textures.detail_gain(np.random.default_rng(0), (64, 96), 0.1, 0.1)
    assert gain.shape == (64, 96) and 0.75 < gain.min() and gain.max() < 1.25


def test_enrich_material():
    from sim_envs.scenes.materials import RICH_WALL_STRENGTH, enrich_material
    from sim_envs.scenes.scene import Material

    plain = Material("metal_1", (0.5, 0.5, 0.52), None, 1.0)
    rich = enrich_material(plain, np.random.default_rng(0))
    assert rich.name == plain.name and rich.rgb == (1.0, 1.0, 1.0) and rich.tile_m == 1.0
    np.testing.assert_allclose(rich.texture.reshape(-1, 3).mean(0), np.array(plain.rgb) * 255, rtol=0.06)
    assert enrich_material(plain, np.random.default_rng(0), texture_density=0.0) is plain
    wall = Material("wall_1", (1.0, 1.0, 1.0), textures.paint(np.random.default_rng(0)), 2.0)
    soft = enrich_material(wall, np.random.default_rng(1), strength=RICH_WALL_STRENGTH)
    full = enrich_material(wall, np.random.default_rng(1))
    assert soft.texture.std() < full.texture.std()


def test_material_bank_density():
    full = MaterialBank(np.random.default_rng(0), 1.0)
    none = MaterialBank(np.random.default_rng(0), 0.0)
    for slot in SLOTS:
        a, b = full.unique(slot), none.unique(slot)
        assert b.texture is None
        if SLOTS[slot].texture is not None and SLOTS[slot].propensity == 1.0:
            assert a.texture is not None
    # shared slots are shared, unique ones are not
    assert full.shared("wood") is full.shared("wood")
    assert full.unique("poster") is not full.unique("poster")
