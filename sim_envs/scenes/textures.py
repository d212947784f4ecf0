"""Procedural textures for indoor scenes: wood, carpet, tiles, wallpaper, fabric, paint, posters, book covers, screens.

Every function takes a ``numpy.random.Generator`` (the only source of randomness: same generator state, same bytes)
and returns an (h, w, 3) uint8 RGB image (row 0 at the top). Repeating textures (wood, carpet, tiles, wallpaper,
fabric, paint, concrete) tile seamlessly: their noise is periodic and their patterns have an integer number of periods
per image, so a surface can repeat them every ``Material.tile_m`` metres without visible seams. Posters, book
covers, screens, windows and whiteboards are single images stretched once over a face.

Direct SLAM needs texture (image gradients) but real rooms also have low-texture surfaces: :func:`paint` is almost
flat on purpose, and :func:`scale_contrast` scales any texture towards its mean colour (the scene generator's
``texture_density``). :func:`detailed` does the opposite for ``rich`` rooms: it raises a texture's contrast and
overlays wear at several scales (mid-scale blotches, fine grain, specks), as real surfaces have.
"""

from __future__ import annotations

import cv2
import numpy as np

TEXTURE_SIZE = 256  # pixels per side of a repeating texture (ours: ~4 mm per pixel at 1 m per tile)
GRAIN_TEXELS: tuple[int, ...] = (8, 4)  # :func:`detail_gain`'s fine grain, an octave per cell size in texels (fitted)
_WORDS = (
    "SLAM", "DEPTH", "MAP", "ROOM", "OFFICE", "NOTES", "PLAN", "DATA", "VISION", "TEAM", "GOALS", "2017", "CNN",
    "KEY", "FRAME", "LOOP", "POSE", "GRAPH", "MEETING", "IDEAS", "ART", "CITY", "NATURE", "MUSIC", "TRAVEL",
)  # fmt: skip
_MARKERS = ((30.0, 30.0, 140.0), (20.0, 20.0, 20.0), (170.0, 30.0, 30.0), (30.0, 120.0, 40.0))  # whiteboard inks
_FONTS = (cv2.FONT_HERSHEY_SIMPLEX, cv2.FONT_HERSHEY_DUPLEX, cv2.FONT_HERSHEY_TRIPLEX, cv2.FONT_HERSHEY_COMPLEX)


def periodic_noise(rng: np.random.Generator, size: int, cells: int) -> np.ndarray:
    """Smooth noise that tiles: (size, size) float32 in about [0, 1], ``cells`` random values per period, bicubic."""
    cells = max(2, int(cells))
    grid = rng.random((cells, cells)).astype(np.float32)
    pad = 2
    big = np.pad(grid, pad, mode="wrap")
    scale = size / cells
    up = cv2.resize(
        big, (int(round(big.shape[1] * scale)), int(round(big.shape[0] * scale))), interpolation=cv2.INTER_CUBIC
    )
    o = int(round(pad * scale))
    return up[o : o + size, o : o + size]


def fractal_noise(
    rng: np.random.Generator, size: int, base_cells: int = 4, octaves: int = 4, persistence: float = 0.5
) -> np.ndarray:
    """Octaves of :func:`periodic_noise` (cells doubling, amplitude times ``persistence``): (size, size) in [0, 1]."""
    total = np.zeros((size, size), np.float32)
    amp, norm = 1.0, 0.0
    for k in range(octaves):
        total += amp * periodic_noise(rng, size, base_cells * 2**k)
        norm += amp
        amp *= persistence
    total /= norm
    lo, hi = float(total.min()), float(total.max())
    return (total - lo) / max(hi - lo, 1e-6)


def _colourise(intensity: np.ndarray, dark: np.ndarray, light: np.ndarray) -> np.ndarray:
    """Blend two RGB colours (3,) in [0, 255] by ``intensity`` (h, w) in [0, 1] -> (h, w, 3) uint8."""
    t = np.clip(intensity, 0.0, 1.0)[..., None]
    return np.clip(dark * (1 - t) + light * t, 0, 255).astype(np.uint8)


def _jitter_colour(rng: np.random.Generator, rgb: tuple[float, float, float], amount: float = 0.08) -> np.ndarray:
    """An RGB colour (3,) float in [0, 255] near ``rgb`` (0-1 floats), each channel jittered by +- ``amount``."""
    return np.clip(np.asarray(rgb) + rng.uniform(-amount, amount, 3), 0, 1) * 255.0


def wood(rng: np.random.Generator, rgb: tuple[float, float, float] = (0.55, 0.36, 0.2),
         size: int = TEXTURE_SIZE) -> np.ndarray:  # fmt: skip
    """Wood grain along the image's x axis: warped growth rings plus fine streaks."""
    y = np.linspace(0, 1, size, endpoint=False, dtype=np.float32)[:, None]
    rings = int(rng.integers(8, 18))
    warp = fractal_noise(rng, size, 2, 3) - 0.5
    streak = periodic_noise(rng, size, 2)
    ring = 0.5 + 0.5 * np.sin(2 * np.pi * (rings * y + 0.8 * warp))
    rows = rng.random((size, 1)).astype(np.float32)  # fine streaks along the grain, smoothed across it (periodic)
    fine = cv2.GaussianBlur(np.pad(rows, ((4, 4), (0, 0)), mode="wrap"), (1, 0), 0, sigmaY=1.0)[4:-4]
    grain = fractal_noise(rng, size, 16, 3)
    intensity = 0.45 * ring**3 + 0.25 * streak + 0.15 * grain + 0.15 * fine
    base = _jitter_colour(rng, rgb, 0.05)
    return _colourise(intensity, base * 0.6, np.minimum(base * 1.25, 255))


def planks(rng: np.random.Generator, rgb: tuple[float, float, float] = (0.55, 0.36, 0.2),
           size: int = TEXTURE_SIZE) -> np.ndarray:  # fmt: skip
    """Floorboards along the image's x axis: 4-8 boards per tile, each its own cut of grain and tone, dark joints."""
    grain = wood(rng, rgb, size).astype(np.float32)
    n = int(rng.choice([4, 6, 8]))
    edges = np.linspace(0, size, n + 1).round().astype(int)  # board k spans rows edges[k]:edges[k + 1]
    img = np.empty_like(grain)
    joint = max(1, size // 128)
    for k in range(n):
        band = np.roll(grain, int(rng.integers(size)), axis=0)[: edges[k + 1] - edges[k]]
        band = np.roll(band, int(rng.integers(size)), axis=1) * rng.uniform(0.82, 1.12)
        end = int(rng.integers(size))  # one butt joint per board and tile, staggered
        band[:, end : end + joint] *= 0.45
        band[:joint] *= 0.45
        img[edges[k] : edges[k + 1]] = band
    img = np.roll(img, edges[1] // 2, axis=0)  # the image's border runs along the middle of a board, not a joint
    return np.clip(img, 0, 255).astype(np.uint8)


def carpet(rng: np.random.Generator, rgb: tuple[float, float, float] = (0.45, 0.4, 0.5),
           size: int = TEXTURE_SIZE) -> np.ndarray:  # fmt: skip
    """Carpet: dense fibre noise over soft blotches."""
    fibres = rng.random((size, size)).astype(np.float32)
    fibres = cv2.GaussianBlur(np.pad(fibres, 4, mode="wrap"), (0, 0), 0.8)[4:-4, 4:-4]
    blotch = fractal_noise(rng, size, 4, 3)
    intensity = 0.55 * fibres + 0.45 * blotch
    base = _jitter_colour(rng, rgb, 0.05)
    return _colourise((intensity - intensity.min()) / np.ptp(intensity), base * 0.65, np.minimum(base * 1.3, 255))


def tiles(rng: np.random.Generator, rgb: tuple[float, float, float] = (0.8, 0.78, 0.72),
          size: int = TEXTURE_SIZE) -> np.ndarray:  # fmt: skip
    """Square floor/wall tiles (2-4 per side) with grout lines, a slightly different shade per tile and speckles."""
    n = int(rng.integers(2, 5))
    step = size / n
    base = _jitter_colour(rng, rgb, 0.06)
    img = np.empty((size, size, 3), np.float32)
    checker = rng.random() < 0.3
    for i in range(n):
        for j in range(n):
            shade = 1.0 + rng.uniform(-0.06, 0.06)
            if checker and (i + j) % 2:
                shade *= 0.55
            img[int(i * step) : int((i + 1) * step), int(j * step) : int((j + 1) * step)] = base * shade
    speck = fractal_noise(rng, size, 32, 2)[..., None]
    img *= 0.9 + 0.2 * speck
    grout = _jitter_colour(rng, (0.35, 0.35, 0.33), 0.05)
    width = max(2, size // 96)
    for k in range(n):
        a = int(round(k * step))
        img[:, max(0, a - width // 2) : a + (width + 1) // 2] = grout
        img[max(0, a - width // 2) : a + (width + 1) // 2, :] = grout
    if width // 2:
        img[:, -(width // 2) :] = grout
        img[-(width // 2) :, :] = grout
    return np.clip(img, 0, 255).astype(np.uint8)


def wallpaper(rng: np.random.Generator, rgb: tuple[float, float, float] = (0.85, 0.8, 0.7),
              size: int = TEXTURE_SIZE) -> np.ndarray:  # fmt: skip
    """Wallpaper: a repeated motif (stripes, dots, diamonds or flowers) on a plain ground, tiling exactly."""
    base = _jitter_colour(rng, rgb, 0.06)
    ink = np.clip(base * rng.uniform(0.55, 0.8) + rng.uniform(-30, 30, 3), 0, 255)
    img = np.empty((size, size, 3), np.float32)
    img[:] = base
    kind = rng.integers(0, 4)
    reps = int(rng.choice([4, 8]))
    step = size // reps
    colour = tuple(float(c) for c in ink)
    if kind == 0:  # stripes
        width = int(rng.integers(step // 6, step // 2))
        for k in range(reps):
            img[:, k * step : k * step + width] = ink
    elif kind == 1:  # dots in a staggered grid
        r = max(2, int(step * rng.uniform(0.12, 0.3)))
        for i in range(reps + 1):
            for j in range(reps + 1):
                off = step // 2 if i % 2 else 0
                cv2.circle(img, (j * step + off, i * step), r, colour, -1, cv2.LINE_AA)
    elif kind == 2:  # diamonds
        for i in range(reps + 1):
            for j in range(reps + 1):
                cx, cy = j * step, i * step
                pts = np.array([[cx, cy - step // 3], [cx + step // 4, cy], [cx, cy + step // 3], [cx - step // 4, cy]])
                cv2.polylines(img, [pts.astype(np.int32)], True, colour, max(1, step // 16), cv2.LINE_AA)
    else:  # small flowers
        r = max(2, step // 6)
        for i in range(reps + 1):
            for j in range(reps + 1):
                cx, cy = j * step + (step // 2 if i % 2 else 0), i * step
                for a in range(5):
                    ang = 2 * np.pi * a / 5
                    p = (int(cx + 1.2 * r * np.cos(ang)), int(cy + 1.2 * r * np.sin(ang)))
                    cv2.circle(img, p, r, colour, -1, cv2.LINE_AA)
                cv2.circle(img, (cx, cy), max(1, r // 2), tuple(float(c) for c in base * 0.9), -1, cv2.LINE_AA)
    # motifs are drawn at both x = 0 and x = size (and y), so each half appears on its side and the image tiles
    img *= (0.93 + 0.07 * fractal_noise(rng, size, 8, 2))[..., None]
    return np.clip(img, 0, 255).astype(np.uint8)


def fabric(rng: np.random.Generator, rgb: tuple[float, float, float] = (0.4, 0.45, 0.6),
           size: int = TEXTURE_SIZE) -> np.ndarray:  # fmt: skip
    """Woven fabric: a fine over-under weave, optional check pattern, soft folds."""
    x = np.arange(size, dtype=np.float32)
    period = size / int(rng.choice([32, 48, 64]))
    wx = 0.5 + 0.5 * np.sin(2 * np.pi * x / period)
    weave = 0.5 * (wx[None, :] + wx[:, None])
    folds = fractal_noise(rng, size, 3, 3)
    intensity = 0.35 * weave + 0.45 * folds + 0.2 * rng.random((size, size)).astype(np.float32)
    base = _jitter_colour(rng, rgb, 0.08)
    img = _colourise(intensity, base * 0.6, np.minimum(base * 1.2, 255)).astype(np.float32)
    if rng.random() < 0.5:  # checks / tartan
        n = int(rng.choice([2, 4]))
        band = (np.floor(x / (size / n)) % 2).astype(np.float32)
        img *= (0.8 + 0.1 * (band[None, :] + band[:, None]))[..., None]
    return np.clip(img, 0, 255).astype(np.uint8)


def paint(rng: np.random.Generator, rgb: tuple[float, float, float] = (0.9, 0.9, 0.88),
          size: int = TEXTURE_SIZE // 2) -> np.ndarray:  # fmt: skip
    """Plain painted plaster: nearly uniform (a deliberately low-texture surface), +-2 % soft variation."""
    base = _jitter_colour(rng, rgb, 0.02)
    return _colourise(fractal_noise(rng, size, 4, 3), base * 0.98, np.minimum(base * 1.02, 255))


def concrete(rng: np.random.Generator, rgb: tuple[float, float, float] = (0.6, 0.6, 0.58),
             size: int = TEXTURE_SIZE) -> np.ndarray:  # fmt: skip
    """Concrete or stone: multi-scale noise with dark pores."""
    n = fractal_noise(rng, size, 8, 5, 0.6)
    pores = (periodic_noise(rng, size, 48) > 0.82).astype(np.float32)
    base = _jitter_colour(rng, rgb, 0.05)
    return _colourise(n - 0.3 * pores, base * 0.75, np.minimum(base * 1.2, 255))


def _random_colour(rng: np.random.Generator, saturated: bool = True) -> tuple[float, float, float]:
    """A random BGR/RGB-agnostic colour tuple in [0, 255] (vivid hues when ``saturated``)."""
    hsv = np.array([[[rng.integers(0, 180), rng.integers(120, 255) if saturated else rng.integers(0, 80),
                      rng.integers(90, 255)]]], np.uint8)  # fmt: skip
    return tuple(float(c) for c in cv2.cvtColor(hsv, cv2.COLOR_HSV2RGB)[0, 0])


def _put_text(img: np.ndarray, rng: np.random.Generator, text: str, org: tuple[int, int], height_px: int,
              colour: tuple[float, float, float]) -> None:  # fmt: skip
    """Draw ``text`` into the float32 image ``img`` (h, w, 3) in place, baseline at ``org``, cap height ~``height_px``.

    OpenCV draws text into uint8 images only: the text is drawn as an anti-aliased coverage mask and blended.
    """
    font = _FONTS[int(rng.integers(len(_FONTS)))]
    scale = height_px / 22.0
    mask = np.zeros(img.shape[:2], np.uint8)
    cv2.putText(mask, text, org, font, scale, 255, max(1, int(round(scale * 2))), cv2.LINE_AA)
    alpha = (mask.astype(np.float32) / 255.0)[..., None]
    img *= 1.0 - alpha
    img += alpha * np.asarray(colour, np.float32)


def poster(rng: np.random.Generator, width: int = 192, height: int = 256) -> np.ndarray:
    """A poster or framed picture: coloured background, random shapes, a title and lines of text (not tiling)."""
    img = np.empty((height, width, 3), np.float32)
    top, bottom = np.array(_random_colour(rng)), np.array(_random_colour(rng, saturated=False))
    t = np.linspace(0, 1, height, dtype=np.float32)[:, None, None]
    img[:] = top * (1 - t) + bottom * t
    for _ in range(int(rng.integers(4, 12))):
        colour = _random_colour(rng)
        kind = rng.integers(0, 3)
        cx, cy = int(rng.integers(0, width)), int(rng.integers(0, height))
        s = int(rng.integers(width // 10, width // 3))
        if kind == 0:
            cv2.circle(img, (cx, cy), s, colour, -1, cv2.LINE_AA)
        elif kind == 1:
            cv2.rectangle(img, (cx - s, cy - s // 2), (cx + s, cy + s // 2), colour, -1)
        else:
            pts = rng.integers(-s, s, (3, 2)) + np.array([cx, cy])
            cv2.fillPoly(img, [pts.astype(np.int32)], colour, cv2.LINE_AA)
    ink = (20.0, 20.0, 20.0) if rng.random() < 0.5 else (245.0, 245.0, 245.0)
    _put_text(img, rng, str(rng.choice(_WORDS)), (width // 12, height // 6), height // 10, ink)
    for k in range(int(rng.integers(0, 4))):
        words = " ".join(str(w) for w in rng.choice(_WORDS, 2))
        _put_text(img, rng, words.lower(), (width // 12, int(height * (0.72 + 0.08 * k))), height // 28, ink)
    border = max(3, width // 24)
    cv2.rectangle(img, (0, 0), (width - 1, height - 1), (30.0, 30.0, 30.0), border)
    return np.clip(img, 0, 255).astype(np.uint8)


def book_cover(rng: np.random.Generator, width: int = 64, height: int = 96) -> np.ndarray:
    """A book's cover or spine: plain colour with a band and a few letters."""
    colour = np.array(_random_colour(rng))
    img = np.empty((height, width, 3), np.float32)
    img[:] = colour
    band = np.array(_random_colour(rng, saturated=False))
    y0 = int(rng.integers(height // 6, height // 2))
    img[y0 : y0 + max(2, height // 8)] = band
    _put_text(img, rng, str(rng.choice(_WORDS))[:4], (width // 10, height - height // 6), height // 10,
              (240.0, 240.0, 230.0))  # fmt: skip
    return np.clip(img, 0, 255).astype(np.uint8)


def screen(rng: np.random.Generator, width: int = 160, height: int = 100) -> np.ndarray:
    """A monitor or TV screen showing windows with lines of text (static: the world must not change over time)."""
    img = np.empty((height, width, 3), np.float32)
    img[:] = np.array(_random_colour(rng, saturated=False)) * 0.5
    for _ in range(int(rng.integers(1, 4))):
        x0, y0 = int(rng.integers(0, width // 2)), int(rng.integers(0, height // 2))
        x1, y1 = (
            x0 + int(rng.integers(width // 3, width // 2 + 1)),
            y0 + int(rng.integers(height // 3, height // 2 + 1)),
        )
        cv2.rectangle(img, (x0, y0), (x1, y1), (235.0, 235.0, 235.0), -1)
        cv2.rectangle(img, (x0, y0), (x1, y0 + 6), _random_colour(rng), -1)
        for yy in range(y0 + 12, y1 - 3, 6):
            xe = x0 + 4 + int(rng.integers(5, max(6, x1 - x0 - 8)))
            cv2.line(img, (x0 + 4, yy), (xe, yy), (60.0, 60.0, 60.0), 1)
    cv2.rectangle(img, (0, 0), (width - 1, height - 1), (15.0, 15.0, 15.0), 3)
    return np.clip(img, 0, 255).astype(np.uint8)


def window_view(rng: np.random.Generator, width: int = 256, height: int = 192) -> np.ndarray:
    """A window pane seen from inside: frame, mullions, sky with clouds and distant buildings or trees."""
    t = np.linspace(0, 1, height, dtype=np.float32)[:, None, None]
    sky_top, sky_low = np.array([90.0, 140.0, 220.0]), np.array([200.0, 220.0, 240.0])
    img = sky_top * (1 - t) + sky_low * t + np.zeros((1, width, 1), np.float32)
    clouds = fractal_noise(rng, max(width, height), 4, 4)[:height, :width]
    img += (np.clip(clouds - 0.55, 0, 1) * 2.0 * 255.0 * 0.5)[..., None]
    horizon = int(height * rng.uniform(0.55, 0.75))
    x = 0
    while x < width:  # skyline of buildings or tree tops
        w = int(rng.integers(width // 12, width // 5))
        h = int(rng.integers(height // 12, height // 3))
        colour = np.array(_random_colour(rng, saturated=False)) * 0.6
        if rng.random() < 0.5:
            cv2.rectangle(img, (x, horizon - h), (x + w, height), tuple(float(c) for c in colour), -1)
        else:
            green = (40.0 + rng.uniform(0, 40), 90.0 + rng.uniform(0, 50), 40.0)
            cv2.circle(img, (x + w // 2, horizon - h // 2), max(4, w // 2), green, -1, cv2.LINE_AA)
        x += w
    img[horizon:] = (
        np.array([110.0, 120.0, 100.0]) + 20 * fractal_noise(rng, width, 8, 2)[: height - horizon, :width, None]
    )
    frame = (235.0, 235.0, 230.0)
    bar = max(4, width // 32)
    cv2.rectangle(img, (0, 0), (width - 1, height - 1), frame, 2 * bar)
    cv2.line(img, (width // 2, 0), (width // 2, height), frame, bar)
    if rng.random() < 0.5:
        cv2.line(img, (0, height // 2), (width, height // 2), frame, bar)
    return np.clip(img, 0, 255).astype(np.uint8)


def whiteboard(rng: np.random.Generator, width: int = 256, height: int = 128) -> np.ndarray:
    """A whiteboard with an aluminium frame and a few marker scribbles and words."""
    img = np.full((height, width, 3), 245.0, np.float32)
    for _ in range(int(rng.integers(2, 6))):
        colour = _MARKERS[int(rng.integers(len(_MARKERS)))]
        if rng.random() < 0.5:
            org = (int(rng.integers(5, width // 2)), int(rng.integers(20, height - 5)))
            _put_text(img, rng, str(rng.choice(_WORDS)), org, height // 8, colour)
        else:
            pts = np.cumsum(rng.normal(0, width / 30, (12, 2)), axis=0) + [width / 2, height / 2]
            cv2.polylines(img, [pts.astype(np.int32)], False, colour, 2, cv2.LINE_AA)
    cv2.rectangle(img, (0, 0), (width - 1, height - 1), (170.0, 170.0, 175.0), max(3, width // 48))
    return np.clip(img, 0, 255).astype(np.uint8)


def door_panel(rng: np.random.Generator, rgb: tuple[float, float, float] = (0.6, 0.45, 0.3),
               width: int = 128, height: int = 256) -> np.ndarray:  # fmt: skip
    """A door leaf: wood grain running vertically with two or four recessed panels and a handle."""
    grain = wood(rng, rgb, size=max(width, height))
    img = np.ascontiguousarray(np.rot90(grain)[:height, :width]).astype(np.float32)
    rows = int(rng.choice([2, 3]))
    m = width // 8
    h = (height - (rows + 1) * m) // rows
    dark = tuple(float(c) for c in img.reshape(-1, 3).mean(0) * 0.7)
    for r in range(rows):
        y0 = m + r * (h + m)
        cv2.rectangle(img, (m, y0), (width - m, y0 + h), dark, max(2, width // 40))
    cv2.circle(img, (width - width // 8, height // 2), max(3, width // 20), (200.0, 200.0, 190.0), -1, cv2.LINE_AA)
    return np.clip(img, 0, 255).astype(np.uint8)


def page(rng: np.random.Generator, width: int = 96, height: int = 128) -> np.ndarray:
    """A sheet of paper or a printout: off-white with a heading, lines of text and sometimes a figure (not tiling)."""
    paper = np.array([rng.uniform(225, 250)] * 3) - rng.uniform(0, 20, 3) * (rng.random() < 0.3)
    img = np.empty((height, width, 3), np.float32)
    img[:] = paper
    margin, pitch = width // 10, max(4, height // int(rng.integers(14, 24)))
    y = margin + pitch
    if rng.random() < 0.6:  # a heading
        cv2.rectangle(img, (margin, margin), (width - margin - int(rng.integers(0, width // 3)), margin + pitch),
                      _random_colour(rng), -1)  # fmt: skip
        y += pitch
    figure = rng.random() < 0.35
    while y < height - margin:
        if figure and y > height // 3:  # a chart or photo block across a few lines
            h = min(int(rng.integers(3, 6)) * pitch, height - margin - y)
            cv2.rectangle(img, (margin, y), (width - margin, y + h), _random_colour(rng), -1)
            y, figure = y + h + pitch, False
            continue
        end = width - margin - int(rng.integers(0, width // 3))
        cv2.line(img, (margin, y), (end, y), (55.0, 55.0, 60.0), max(1, pitch // 4))
        y += pitch
    return np.clip(img, 0, 255).astype(np.uint8)


def clock_face(rng: np.random.Generator, size: int = 96) -> np.ndarray:
    """A wall clock's face: a pale dial, twelve hour ticks, two hands at a random time, a dark rim (not tiling)."""
    img = np.full((size, size, 3), rng.uniform(215, 245), np.float32)
    c, r = size // 2, size // 2 - 2
    cv2.circle(img, (c, c), r, (35.0, 35.0, 35.0), max(2, size // 16))
    for k in range(12):
        a = 2 * np.pi * k / 12
        p0 = (int(c + 0.75 * r * np.cos(a)), int(c + 0.75 * r * np.sin(a)))
        p1 = (int(c + 0.88 * r * np.cos(a)), int(c + 0.88 * r * np.sin(a)))
        cv2.line(img, p0, p1, (30.0, 30.0, 30.0), max(1, size // 32))
    for length, width in ((0.5, size // 20), (0.75, size // 32)):
        a = rng.uniform(0, 2 * np.pi)
        cv2.line(img, (c, c), (int(c + length * r * np.cos(a)), int(c + length * r * np.sin(a))), (20.0, 20.0, 20.0),
                 max(1, width), cv2.LINE_AA)  # fmt: skip
    return np.clip(img, 0, 255).astype(np.uint8)


def detail_gain(rng: np.random.Generator, shape: tuple[int, int], mid: float, fine: float,
                specks: float = 0.0, speck_depth: float = 0.35) -> np.ndarray:  # fmt: skip
    """Wear at several scales as a multiplicative gain: (h, w) float32 around 1.

    Mid-scale blotches (fractal noise, 6 cells per image side and 3 octaves, scaled to +-``mid``), fine grain (one
    octave of noise per cell size of :data:`GRAIN_TEXELS` pixels, together +-``fine``) and dark specks (the darkest
    ``specks`` share of a 3-pixel noise, darkened by ``speck_depth``). Made periodic over a square of side
    ``max(h, w)`` and cropped, so a square texture keeps tiling.
    """
    h, w = int(shape[0]), int(shape[1])
    n = max(h, w)
    blotch = fractal_noise(rng, n, 6, 3) - 0.5
    grain = sum(periodic_noise(rng, n, max(2, n // t)) for t in GRAIN_TEXELS) / len(GRAIN_TEXELS) - 0.5
    gain = (1.0 + 2.0 * mid * blotch) * (1.0 + 2.0 * fine * grain)
    if specks > 0:
        dots = periodic_noise(rng, n, max(2, n // 3))
        gain *= np.where(dots < np.quantile(dots, specks), np.float32(1.0 - speck_depth), np.float32(1.0))
    return np.ascontiguousarray(gain[:h, :w], dtype=np.float32)


def detailed(texture: np.ndarray, rng: np.random.Generator, contrast: float, mid: float, fine: float,
             specks: float = 0.0, speck_depth: float = 0.35) -> np.ndarray:  # fmt: skip
    """``texture`` (h, w, 3) uint8 with its deviation from its mean colour scaled by ``contrast`` (> 1: more local
    contrast) and then multiplied by :func:`detail_gain` (``mid``, ``fine``, ``specks``, ``speck_depth``):
    (h, w, 3) uint8, tiling when ``texture`` is square and tiles."""
    img = texture.astype(np.float32)
    mean = img.reshape(-1, 3).mean(0)
    img = mean + float(contrast) * (img - mean)
    img *= detail_gain(rng, img.shape[:2], mid, fine, specks, speck_depth)[..., None]
    return np.clip(img + 0.5, 0, 255).astype(np.uint8)


def scale_contrast(texture: np.ndarray, strength: float) -> np.ndarray:
    """Scale a texture's deviation from its mean colour by ``strength`` in [0, 1] (0 = flat): (h, w, 3) uint8."""
    strength = float(np.clip(strength, 0.0, 1.0))
    if strength >= 1.0:
        return texture
    img = texture.astype(np.float32)
    mean = img.reshape(-1, 3).mean(0)
    return np.clip(mean + strength * (img - mean) + 0.5, 0, 255).astype(np.uint8)
