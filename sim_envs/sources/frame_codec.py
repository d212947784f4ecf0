"""Lossless, compact bytes for one frame of the frame cache (:mod:`sim_envs.sources.frame_cache`): every array comes
back with
the same dtype, shape and bytes (NaN payloads and -0.0 included), and one array (the RGB image) can be decoded
without the others.

Each array goes through a reversible transform that leaves small numbers where neighbouring pixels agree, then
Zstandard (level :data:`ZSTD_LEVEL`). The encoder tries every transform that applies to the array's dtype and keeps
the shortest result (the choice is stored). For an array of :data:`SAMPLE_MIN_BYTES` or more it compresses a sample
of each transform's bytes first (:func:`estimated_sizes`: evenly spaced chunks, 1/8 of them) and compresses in full
only the transforms within :data:`SAMPLE_MARGIN` of the best estimate, so that a frame is not compressed four times
over. A :class:`FrameEncoder` (the frame cache keeps one per
sequence) remembers each array's choice and makes it again only every :data:`RECHOOSE_EVERY` frames: consecutive
frames of a sequence pick the same transforms. The choice never changes what comes back, only how short it is:

- ``u8-left``: uint8 images, channel planes, each pixel minus its left neighbour (mod 256). Camera images with sensor
  noise compress to about 55 % (a 320x240 RGB frame of the ``kinect`` camera: 230 -> 125 KB).
- ``b32-delta2``: 4-byte arrays (float32 depth, int32 instances) as their 32-bit patterns, differences along the row,
  then along the column (wrapping int32 arithmetic: exact for any bit pattern), the four byte planes apart. Rendered
  planar depth: 300 -> 64 KB.
- ``palette``: arrays with at most 65 536 distinct values (labels, a quantising depth sensor's depth): the sorted
  distinct values and each element's index as uint8 or uint16. A Kinect-like sensor depth: 300 -> 4 KB.
- ``raw``: the bytes as they are (any dtype).

Format of a frame (:data:`FRAME_FORMAT`): ``MAGIC``, a little-endian uint32 header length, a JSON header (the frame's
index and timestamp, and per array its name, dtype, shape, transform, byte offset and length in the payload, and the
palette's length), then the payload. Floats in JSON round-trip exactly (``repr``).
"""

from __future__ import annotations

import json
import struct
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import zstandard
from numba import njit

from sim_envs.errors import SimEnvError

FRAME_FORMAT = "cnnslam-frame/1"  # bump when the bytes of a stored frame change meaning
MAGIC = b"CNNSLAMFRAME1\n"
# Zstandard level 1 (its default is 3): on 231 kinect frames of the main job's nine sequences (every 50th) a frame
# encodes in 4.5 instead of 6.2 ms and decodes in 0.80 instead of 0.88 ms, and is as short (209.9 against 210.3 KB)
ZSTD_LEVEL = 1
PALETTE_MAX = 65536  # distinct values a palette may hold (uint16 indices)
PALETTE_SAMPLE_STEP = 16  # the palette is tried only when every 16th element has at most ...
PALETTE_SAMPLE_MAX = 2048  # ... this many distinct values (rendered depth has thousands: 0.4 ms to find out)
SAMPLE_MIN_BYTES = 65536  # arrays this large choose their transform from compressed samples ...
SAMPLE_CHUNKS = 8  # ... of this many evenly spaced chunks of a transform's bytes, ...
SAMPLE_SHARE = 8  # ... 1/8 of the bytes in all; ...
SAMPLE_MARGIN = 1.1  # ... every transform whose estimate is within 10 % of the best is compressed in full
# A FrameEncoder chooses again every 30th frame (one second of a 30 Hz sequence) and otherwise applies the array's last
# choice: the kinect frames of office0 and office2 (1 800 and 1 500) encode in 3.3 instead of 5.6 and 6.2 ms, 193.7
# against 194.8 and 230.2 against 231.3 KB a frame (choosing on every frame, or every 10th, 100th: within 0.1 KB)
RECHOOSE_EVERY = 30
_HEADER_LEN = struct.Struct("<I")


class FrameCodecError(SimEnvError, ValueError):
    """Bytes that are not a frame of this format (a damaged or foreign file)."""


@dataclass(frozen=True)
class EncodedFrame:
    """A frame's scalars and arrays as they come back from :func:`decode_frame`: ``index``, ``timestamp`` (seconds),
    ``arrays`` (name -> array; only the names asked for)."""

    index: int
    timestamp: float
    arrays: dict[str, np.ndarray]


# ------------------------------------------------------------------------------------------------- the transforms
def _u8_left(a: np.ndarray) -> bytes:
    planes = a.reshape(a.shape[0], a.shape[1], -1).transpose(2, 0, 1)  # (C, H, W)
    out = np.empty(planes.shape, np.uint8)
    out[:, :, 0] = planes[:, :, 0]
    np.subtract(planes[:, :, 1:], planes[:, :, :-1], out=out[:, :, 1:])  # uint8 arithmetic wraps (mod 256)
    return out.tobytes()


@njit(cache=True, nogil=True)
def _u8_left_undo(planes: np.ndarray) -> np.ndarray:  # pragma: no cover - compiled
    """(C, H, W) uint8 left differences -> (H, W, C) uint8 running sums along each row, mod 256."""
    c, h, w = planes.shape
    out = np.empty((h, w, c), np.uint8)
    for y in range(h):
        for k in range(c):
            acc = 0
            for x in range(w):
                acc = (acc + planes[k, y, x]) & 0xFF
                out[y, x, k] = acc
    return out


def _u8_left_inverse(raw: bytes, shape: tuple[int, ...]) -> np.ndarray:
    h, w = shape[0], shape[1]
    c = int(np.prod(shape[2:], dtype=np.int64))
    planes = np.frombuffer(raw, np.uint8).reshape(c, h, w)
    return _u8_left_undo(planes).reshape(shape)  # the running sums wrap mod 256: the differences undone exactly


def _b32_delta2(a: np.ndarray) -> bytes:
    bits = np.ascontiguousarray(a).view(np.int32).reshape(a.shape[0], -1)
    with np.errstate(over="ignore"):
        d = np.empty_like(bits)
        d[:, 0] = bits[:, 0]
        np.subtract(bits[:, 1:], bits[:, :-1], out=d[:, 1:])
        e = np.empty_like(d)
        e[0] = d[0]
        np.subtract(d[1:], d[:-1], out=e[1:])
    return np.ascontiguousarray(e.view(np.uint8).reshape(-1, 4).T).tobytes()  # byte planes


@njit(cache=True, nogil=True)
def _b32_delta2_undo(planes: np.ndarray, rows: int) -> np.ndarray:  # pragma: no cover - compiled
    """(4, N) little-endian byte planes of the twice-differenced 32-bit patterns -> (rows, N / rows) uint32
    patterns: running sums down each column, then along each row, mod 2^32 (the encoder's wrapping int32)."""
    cols = planes.shape[1] // rows
    out = np.empty((rows, cols), np.uint32)
    column = np.zeros(cols, np.int64)
    for r in range(rows):
        acc = 0
        for j in range(cols):
            i = r * cols + j
            e = (np.int64(planes[0, i]) | (np.int64(planes[1, i]) << 8) | (np.int64(planes[2, i]) << 16)
                 | (np.int64(planes[3, i]) << 24))
            column[j] = (column[j] + e) & 0xFFFFFFFF
            acc = (acc + column[j]) & 0xFFFFFFFF
            out[r, j] = acc
    return out


def _b32_delta2_inverse(raw: bytes, shape: tuple[int, ...], dtype: np.dtype) -> np.ndarray:
    planes = np.frombuffer(raw, np.uint8).reshape(4, -1)
    return _b32_delta2_undo(planes, int(shape[0])).view(dtype).reshape(shape)


def _palette(a: np.ndarray) -> tuple[bytes, int] | None:
    """The palette's bytes and length, or None when the array has too many distinct values for one to pay (a
    strided sample of it already has more than :data:`PALETTE_SAMPLE_MAX`) or for uint16 indices. The bytes are
    those of ``np.unique`` and ``np.searchsorted``, from ``pandas.factorize`` (a hashed pass, then a sort of the
    distinct values alone) for integer patterns."""
    flat = np.ascontiguousarray(a).reshape(-1)
    # distinct bit patterns, so that NaN payloads and -0.0 survive (and NaN is one value, not one per element)
    key = flat.view(f"u{a.dtype.itemsize}") if a.dtype.kind == "f" else flat
    if np.unique(key[::PALETTE_SAMPLE_STEP]).size > PALETTE_SAMPLE_MAX:
        return None
    if key.dtype.kind in "iu":  # np.unique's sorted values and np.searchsorted's indices, from one hashed pass
        import pandas as pd

        index, values = pd.factorize(key, sort=True)
        values = np.asarray(values, dtype=key.dtype)
    else:  # (complex, ...) no hash table of pandas' takes them
        values = np.unique(key)
        index = np.searchsorted(values, key)
    if values.size > PALETTE_MAX:
        return None
    return values.tobytes() + index.astype(np.uint8 if values.size <= 256 else np.uint16).tobytes(), int(values.size)


def _palette_inverse(raw: bytes, shape: tuple[int, ...], dtype: np.dtype, n_values: int) -> np.ndarray:
    key_dtype = np.dtype(f"u{dtype.itemsize}") if dtype.kind == "f" else dtype
    split = n_values * dtype.itemsize
    values = np.frombuffer(raw[:split], key_dtype)
    index = np.frombuffer(raw[split:], np.uint8 if n_values <= 256 else np.uint16)
    return values[index].view(dtype).reshape(shape)


_TRANSFORMS = ("u8-left", "b32-delta2", "palette", "raw")  # in the order they are tried (a tie keeps the first)


def _candidates(a: np.ndarray) -> Iterable[tuple[str, bytes, int]]:
    """(transform, transformed bytes, palette length) of every transform that applies to ``a``."""
    for transform in _TRANSFORMS:
        applied = _apply(a, transform)
        if applied is not None:
            yield transform, applied[0], applied[1]


def _apply(a: np.ndarray, transform: str) -> tuple[bytes, int] | None:
    """(transformed bytes, palette length) of ``a`` under ``transform``, None where it does not apply to ``a``."""
    if transform == "u8-left":
        return (_u8_left(a), 0) if a.dtype == np.uint8 and a.ndim in (2, 3) and a.size else None
    if transform == "b32-delta2":
        return (_b32_delta2(a), 0) if a.dtype.itemsize == 4 and a.ndim >= 2 and a.size else None
    if transform == "palette":  # uint8 indices would be no shorter than uint8 values
        return _palette(a) if a.dtype.itemsize > 1 and a.size >= 1024 else None
    return np.ascontiguousarray(a).tobytes(), 0


def estimated_sizes(compressor: zstandard.ZstdCompressor, candidates: list[bytes]) -> list[int]:
    """For each of ``candidates`` (transformed bytes of one array), the compressed length of a sample of it:
    :data:`SAMPLE_CHUNKS` evenly spaced chunks, 1 / :data:`SAMPLE_SHARE` of its bytes in all, compressed as one
    (about that share of the full length; used to rank the transforms, never stored)."""
    sizes = []
    for raw in candidates:
        n = len(raw)
        chunk = max(n // (SAMPLE_CHUNKS * SAMPLE_SHARE), 1)
        starts = np.linspace(0, max(n - chunk, 0), SAMPLE_CHUNKS).astype(np.int64)
        view = memoryview(raw)
        sizes.append(len(compressor.compress(b"".join(view[int(s): int(s) + chunk] for s in starts))) * n
                     // max(SAMPLE_CHUNKS * chunk, 1))
    return sizes


# ------------------------------------------------------------------------------------------------- a whole frame
def encode_frame(index: int, timestamp: float, arrays: Mapping[str, np.ndarray]) -> bytes:
    """The bytes of one frame: ``index``, ``timestamp`` (seconds) and ``arrays`` (name -> array of any numeric
    dtype and shape; each stored with its shortest transform)."""
    return FrameEncoder(rechoose_every=1).encode(index, timestamp, arrays)


class FrameEncoder:
    """:func:`encode_frame` for the frames of one sequence, in order: an array's transform is chosen (the shortest,
    as :func:`encode_frame` chooses it) on the first frame and every ``rechoose_every``-th frame after it, and on the
    frames in between the last choice for an array of that name, dtype and shape is applied alone (chosen again
    where it no longer applies: a palette that outgrew its bound). What comes back is the same either way."""

    def __init__(self, rechoose_every: int = RECHOOSE_EVERY) -> None:
        if not (isinstance(rechoose_every, int) and rechoose_every >= 1):
            raise FrameCodecError(f"rechoose_every must be an integer >= 1, got {rechoose_every!r}")
        self.rechoose_every = rechoose_every
        self._compressor: zstandard.ZstdCompressor | None = None  # made at first use (it cannot be pickled)
        self._choices: dict[str, tuple[str, str, tuple[int, ...]]] = {}  # name -> (transform, dtype, shape)
        self._frames = 0

    def encode(self, index: int, timestamp: float, arrays: Mapping[str, np.ndarray]) -> bytes:
        """The bytes of one frame (:func:`encode_frame`'s format)."""
        if self._compressor is None:
            self._compressor = zstandard.ZstdCompressor(level=ZSTD_LEVEL)
        choose = self._frames % self.rechoose_every == 0
        self._frames += 1
        entries, blobs, offset = [], [], 0
        for name, value in arrays.items():
            a = np.asarray(value)
            if a.dtype.hasobject:
                raise FrameCodecError(f"array {name!r}: dtype {a.dtype} cannot be stored")
            last = self._choices.get(name)
            applied = None
            if not choose and last is not None and last[1:] == (a.dtype.str, a.shape):
                applied = _apply(a, last[0])
            if applied is not None:
                best = (last[0], self._compressor.compress(applied[0]), applied[1])
            else:
                best = self._shortest(a)
                self._choices[name] = (best[0], a.dtype.str, a.shape)
            entries.append({"name": name, "dtype": a.dtype.str, "shape": list(a.shape), "transform": best[0],
                            "offset": offset, "length": len(best[1]), "values": best[2]})
            blobs.append(best[1])
            offset += len(best[1])
        header = json.dumps({"format": FRAME_FORMAT, "index": int(index), "timestamp": float(timestamp),
                             "arrays": entries}, separators=(",", ":")).encode()
        return b"".join([MAGIC, _HEADER_LEN.pack(len(header)), header, *blobs])

    def __getstate__(self) -> dict[str, Any]:
        """Pickled (a frame cache sent to a worker process, or copied) with its choices, without the compressor."""
        return {**self.__dict__, "_compressor": None}

    def _shortest(self, a: np.ndarray) -> tuple[str, bytes, int]:
        """(transform, compressed bytes, palette length) of the transform of ``a`` that compresses shortest."""
        assert self._compressor is not None
        candidates = list(_candidates(a))
        if a.nbytes >= SAMPLE_MIN_BYTES and len(candidates) > 1:
            estimates = estimated_sizes(self._compressor, [raw for _, raw, _ in candidates])
            bound = SAMPLE_MARGIN * min(estimates)
            candidates = [c for c, e in zip(candidates, estimates, strict=True) if e <= bound]
        best: tuple[str, bytes, int] | None = None
        for transform, raw, n_values in candidates:
            packed = self._compressor.compress(raw)
            if best is None or len(packed) < len(best[1]):
                best = (transform, packed, n_values)
        assert best is not None  # "raw" always applies
        return best


def frame_fields(data: bytes) -> tuple[str, ...]:
    """The names of the arrays a frame's bytes hold."""
    return tuple(e["name"] for e in _header(data)[0]["arrays"])


def decode_frame(data: bytes, names: Iterable[str] | None = None) -> EncodedFrame:
    """The frame in ``data`` (:func:`encode_frame`'s bytes) with the arrays ``names`` (None: all; a name the frame
    does not hold is left out). Arrays are fresh, writable and C-contiguous. :class:`FrameCodecError`
    when ``data`` is not such a frame."""
    header, start = _header(data)
    wanted = None if names is None else set(names)
    decompressor = zstandard.ZstdDecompressor()
    arrays: dict[str, np.ndarray] = {}
    try:
        for e in header["arrays"]:
            if wanted is not None and e["name"] not in wanted:
                continue
            blob = data[start + e["offset"]: start + e["offset"] + e["length"]]
            raw = decompressor.decompress(blob)
            dtype, shape = np.dtype(e["dtype"]), tuple(int(s) for s in e["shape"])
            transform = e["transform"]
            if transform == "u8-left":
                a = _u8_left_inverse(raw, shape)
            elif transform == "b32-delta2":
                a = _b32_delta2_inverse(raw, shape, dtype)
            elif transform == "palette":
                a = _palette_inverse(raw, shape, dtype, int(e["values"]))
            elif transform == "raw":
                a = np.frombuffer(raw, dtype).reshape(shape).copy()
            else:
                raise FrameCodecError(f"unknown transform {transform!r}")
            arrays[e["name"]] = a
    except (zstandard.ZstdError, KeyError, TypeError, ValueError) as exc:
        raise FrameCodecError(f"damaged frame: {exc}") from exc
    return EncodedFrame(int(header["index"]), float(header["timestamp"]), arrays)


def _header(data: bytes) -> tuple[dict[str, Any], int]:
    if not data.startswith(MAGIC) or len(data) < len(MAGIC) + _HEADER_LEN.size:
        raise FrameCodecError("not a frame of the frame cache (bad magic)")
    (n,) = _HEADER_LEN.unpack_from(data, len(MAGIC))
    start = len(MAGIC) + _HEADER_LEN.size
    try:
        header = json.loads(data[start: start + n])
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise FrameCodecError(f"damaged frame header: {exc}") from exc
    if not isinstance(header, dict) or header.get("format") != FRAME_FORMAT:
        raise FrameCodecError(f"frame format {header.get('format') if isinstance(header, dict) else None!r}, "
                              f"expected {FRAME_FORMAT!r}")
    return header, start + n
