"""The frame codec: every array comes back with its dtype, shape and bytes, whatever transform the encoder picked;
one array can be decoded alone; damaged bytes raise."""

from __future__ import annotations

import json
import struct

import numpy as np
import pytest

from sim_envs.sources import frame_codec as fc
from sim_envs.sources.frame_codec import MAGIC, FrameCodecError, decode_frame, encode_frame, frame_fields


def _transforms(data: bytes) -> dict[str, str]:
    (n,) = struct.unpack_from("<I", data, len(MAGIC))
    header = json.loads(data[len(MAGIC) + 4: len(MAGIC) + 4 + n])
    return {e["name"]: e["transform"] for e in header["arrays"]}


def _arrays(rng: np.random.Generator) -> dict[str, np.ndarray]:
    h, w = 48, 64
    yy, xx = np.mgrid[0:h, 0:w]
    depth = (1.0 / (0.2 + 0.001 * xx + 0.002 * yy)).astype(np.float32)
    depth[:5, :7] = 0.0
    depth[10, 10], depth[11, 11], depth[12, 12] = np.nan, -0.0, np.inf
    nan_payload = np.array([0x7FC00123], np.uint32).view(np.float32)[0]  # a NaN with a payload keeps its bits
    depth[13, 13] = nan_payload
    return {
        "rgb": np.clip(xx[..., None] * 3 + rng.integers(0, 9, (h, w, 3)), 0, 255).astype(np.uint8),  # u8-left
        "depth": depth,  # b32-delta2
        "sensor_depth": (np.round(depth * 50) / 50).astype(np.float32),  # a quantised depth: palette
        "labels": (xx // 20).astype(np.uint8),
        "instances": np.where(xx < 30, 3, -1).astype(np.int32),
        "T_world_cam": np.eye(4) + rng.normal(size=(4, 4)),  # raw float64
        "noise": rng.integers(-(2**31), 2**31 - 1, (h, w), dtype=np.int64).astype(np.int32),  # wrapping deltas
        "empty": np.zeros((0, 3), np.float32),
        "wide": rng.integers(0, 1000, 20000).astype(np.uint32) * 4099,  # palette with uint16 indices
    }


def test_every_array_comes_back_byte_for_byte() -> None:
    arrays = _arrays(np.random.default_rng(0))
    data = encode_frame(7, 0.23333333333333334, arrays)
    out = decode_frame(data)
    assert (out.index, out.timestamp) == (7, 0.23333333333333334)
    assert set(out.arrays) == set(arrays) and frame_fields(data) == tuple(arrays)
    for name, a in arrays.items():
        b = out.arrays[name]
        assert b.dtype == a.dtype and b.shape == a.shape and b.tobytes() == a.tobytes(), name
        assert b.flags.c_contiguous and b.flags.writeable
    used = _transforms(data)
    assert used["rgb"] == "u8-left" and used["sensor_depth"] == "palette"
    assert used["T_world_cam"] == "raw" and used["wide"] == "palette"
    assert len(data) < 0.5 * sum(a.nbytes for a in arrays.values())


def test_one_array_alone_and_names_it_does_not_hold() -> None:
    arrays = _arrays(np.random.default_rng(1))
    out = decode_frame(encode_frame(0, 0.0, arrays), ["rgb", "absent"])
    assert list(out.arrays) == ["rgb"] and np.array_equal(out.arrays["rgb"], arrays["rgb"])


@pytest.mark.parametrize("cut", [b"", b"not a frame", MAGIC + b"\x05\x00\x00\x00{bad}"])
def test_damaged_bytes_raise(cut: bytes) -> None:
    with pytest.raises(FrameCodecError):
        decode_frame(cut)


def test_a_truncated_or_foreign_frame_raises() -> None:
    data = encode_frame(0, 0.0, {"rgb": np.zeros((8, 8, 3), np.uint8) + 7})
    with pytest.raises(FrameCodecError):
        decode_frame(data[:-3])
    with pytest.raises(FrameCodecError):
        decode_frame(data.replace(b"cnnslam-frame/1", b"cnnslam-frame/0"))
    with pytest.raises(FrameCodecError):
        encode_frame(0, 0.0, {"bad": np.array([object()])})


@pytest.mark.parametrize("name", ["rgb", "depth", "sensor_depth", "instances", "noise", "labels"])
def test_each_transform_is_exact_on_its_own(name: str) -> None:
    a = _arrays(np.random.default_rng(2))[name]
    if a.dtype == np.uint8:
        back = fc._u8_left_inverse(fc._u8_left(a), a.shape)
        assert back.dtype == a.dtype and back.tobytes() == a.tobytes()
    if a.dtype.itemsize == 4:
        back = fc._b32_delta2_inverse(fc._b32_delta2(a), a.shape, a.dtype)
        assert back.dtype == a.dtype and back.tobytes() == a.tobytes()
    pal = fc._palette(a) if a.dtype.itemsize > 1 else None
    if pal is not None:
        back = fc._palette_inverse(pal[0], a.shape, a.dtype, pal[1])
        assert back.dtype == a.dtype and back.tobytes() == a.tobytes()


def _large_arrays(rng: np.random.Generator) -> dict[str, np.ndarray]:
    """Frame-sized arrays (320x240) as a camera gives them (noise in the images and the depth), each above the
    sampling threshold, each with a clear best transform."""
    h, w = 240, 320
    yy, xx = np.mgrid[0:h, 0:w]
    depth = (1.0 / (0.2 + 0.001 * xx + 0.002 * yy) * (1 + 1e-4 * rng.normal(size=(h, w)))).astype(np.float32)
    return {
        "rgb": np.clip((xx + yy)[..., None] // 2 + rng.integers(0, 9, (h, w, 3)), 0, 255).astype(np.uint8),
        "depth": depth,
        "sensor_depth": (np.round(depth * (1 + 0.01 * rng.normal(size=(h, w)))* 50) / 50).astype(np.float32),
        "instances": np.where(xx < 150, 3, np.where(yy < 100, 8, -1)).astype(np.int32),
    }


def test_sampled_choice_is_lossless_and_picks_what_full_compression_picks(monkeypatch: pytest.MonkeyPatch) -> None:
    arrays = _large_arrays(np.random.default_rng(3))
    assert all(a.nbytes >= fc.SAMPLE_MIN_BYTES for a in arrays.values())
    sampled = encode_frame(1, 0.5, arrays)
    monkeypatch.setattr(fc, "SAMPLE_MIN_BYTES", 1 << 62)  # every transform compressed in full
    full = encode_frame(1, 0.5, arrays)
    assert _transforms(sampled) == _transforms(full)
    assert _transforms(sampled) == {"rgb": "u8-left", "depth": "b32-delta2", "sensor_depth": "palette",
                                    "instances": "b32-delta2"}
    assert sampled == full  # the same choices give the same bytes
    back = decode_frame(sampled)
    assert all(back.arrays[k].tobytes() == a.tobytes() for k, a in arrays.items())


def test_estimated_sizes_follow_the_full_compressed_lengths() -> None:
    import zstandard

    compressor = zstandard.ZstdCompressor(level=fc.ZSTD_LEVEL)
    arrays = _large_arrays(np.random.default_rng(4))
    raws = [raw for _, raw, _ in fc._candidates(arrays["depth"])] + [
        raw for _, raw, _ in fc._candidates(arrays["rgb"])]
    estimates = fc.estimated_sizes(compressor, raws)
    lengths = [len(compressor.compress(r)) for r in raws]
    ratio = np.asarray(estimates, float) / np.asarray(lengths, float)
    assert np.all((ratio > 0.5) & (ratio < 2.0)), ratio
    assert np.argmin(estimates[:-2]) == np.argmin(lengths[:-2])  # the depth's best transform
    assert np.argmin(estimates[-2:]) == np.argmin(lengths[-2:])  # the image's
    assert fc.estimated_sizes(compressor, [b""]) == [0]


def _palette_by_definition(a: np.ndarray) -> tuple[bytes, int] | None:
    """The palette as its definition reads: ``np.unique`` of the bit patterns and ``np.searchsorted`` in them."""
    flat = a.reshape(-1)
    key = flat.view(f"u{a.dtype.itemsize}") if a.dtype.kind == "f" else flat
    if np.unique(key[:: fc.PALETTE_SAMPLE_STEP]).size > fc.PALETTE_SAMPLE_MAX:
        return None
    values = np.unique(key)
    if values.size > fc.PALETTE_MAX:
        return None
    index = np.searchsorted(values, key).astype(np.uint8 if values.size <= 256 else np.uint16)
    return values.tobytes() + index.tobytes(), int(values.size)


def test_the_hashed_palette_gives_the_bytes_of_unique_and_searchsorted() -> None:
    rng = np.random.default_rng(4)
    over = np.arange(200_000, dtype=np.int32)
    over[:: fc.PALETTE_SAMPLE_STEP] = 0  # a sample with one value, the whole with 187 500: no palette
    full = np.arange(100_000, dtype=np.int32) % fc.PALETTE_MAX  # 61 441 values: uint16 indices
    full[:: fc.PALETTE_SAMPLE_STEP] = 0
    cases = {
        "signed": rng.integers(-5, 5, 5000).astype(np.int32),  # negative values sort first, as np.unique sorts
        "wide": rng.integers(0, 1000, 20000).astype(np.uint32) * 4099,
        "quantised depth": (np.round(rng.random(76800) * 400) / 50).astype(np.float32),
        "float64": -np.round(rng.random(9000) * 30) - 0.5,  # bit patterns above 2^63
        "NaN and -0.0": np.array([np.nan, -0.0, 0.0, 1.0] * 1000, np.float32),
        "uint16": rng.integers(0, 300, 5000).astype(np.uint16),
        "one value": np.zeros(2000, np.int32),
        "full": full,
        "over": over,
    }
    for name, a in cases.items():
        assert fc._palette(a) == _palette_by_definition(a), name
    assert fc._palette(over) is None and fc._palette(full)[1] == 61441


def _back(data: bytes, arrays: dict[str, np.ndarray]) -> bool:
    back = decode_frame(data).arrays
    return all(back[k].dtype == a.dtype and back[k].shape == a.shape and back[k].tobytes() == a.tobytes()
               for k, a in arrays.items())


def test_an_encoder_keeps_its_choices_between_rechoices_and_loses_nothing() -> None:
    rng = np.random.default_rng(5)
    quantised = (np.round(rng.random((48, 64)) * 20) / 10).astype(np.float32)  # a palette's array
    smooth = (1.0 + 0.001 * np.arange(48 * 64)).astype(np.float32).reshape(48, 64)  # b32-delta2's
    frames = [{"d": quantised, "rgb": _arrays(rng)["rgb"]}, {"d": smooth}, {"d": smooth}, {"d": smooth}]
    encoder = fc.FrameEncoder(rechoose_every=3)
    data = [encoder.encode(i, 0.1 * i, arrays) for i, arrays in enumerate(frames)]
    assert [_transforms(b)["d"] for b in data] == ["palette", "palette", "palette", "b32-delta2"]
    assert _transforms(encode_frame(1, 0.1, frames[1]))["d"] == "b32-delta2"  # what frame 1 alone would choose
    assert all(_back(b, arrays) for b, arrays in zip(data, frames, strict=True))
    # choosing on every frame gives encode_frame's bytes
    every = fc.FrameEncoder(rechoose_every=1)
    assert [every.encode(i, 0.1 * i, a) for i, a in enumerate(frames)] == [
        encode_frame(i, 0.1 * i, a) for i, a in enumerate(frames)]


def test_a_choice_that_no_longer_applies_is_made_again() -> None:
    rng = np.random.default_rng(6)
    encoder = fc.FrameEncoder(rechoose_every=100)
    few = rng.integers(0, 5, (256, 256)).astype(np.int32)  # a palette ...
    many = rng.integers(0, 2**31 - 1, (256, 256)).astype(np.int32)  # ... which this one outgrows (its sample too)
    other = rng.integers(0, 5, (64, 64)).astype(np.int16)  # the same name, another dtype
    shorter = rng.integers(0, 5, (32, 64)).astype(np.int32)  # ... another shape: chosen again
    data = [encoder.encode(i, 0.0, {"ids": a}) for i, a in enumerate((few, many, other, shorter))]
    assert _transforms(data[0])["ids"] == "palette" and _transforms(data[1])["ids"] != "palette"
    assert all(_back(b, {"ids": a}) for b, a in zip(data, (few, many, other, shorter), strict=True))


def test_an_encoder_pickles_with_its_choices_and_checks_its_interval() -> None:
    import pickle

    encoder = fc.FrameEncoder(rechoose_every=10)
    arrays = {"d": np.round(np.random.default_rng(7).random((40, 40)) * 4).astype(np.float32)}
    first = encoder.encode(0, 0.0, arrays)
    copy = pickle.loads(pickle.dumps(encoder))  # (a frame cache sent to a worker process)
    assert copy.encode(1, 0.0, arrays)[len(MAGIC):] == encoder.encode(1, 0.0, arrays)[len(MAGIC):]
    assert _back(first, arrays)
    for bad in (0, -1, 1.5):
        with pytest.raises(FrameCodecError, match="rechoose_every"):
            fc.FrameEncoder(rechoose_every=bad)
