"""The DBoW2 vocabulary builder (thirdparty.orb_vocabulary): the text format ORB-SLAM3 reads, on tiny inputs."""

from __future__ import annotations

import numpy as np
import pytest

from thirdparty.orb_vocabulary import (
    DEFAULT_VOCABULARY,
    build_vocabulary,
    hamming,
    orb_descriptors,
    read_dbow2_text,
    training_frames,
    words_of,
    write_dbow2_text,
)


def _clustered_descriptors(n_centres: int = 6, per: int = 20, flips: int = 8, seed: int = 0):
    rng = np.random.default_rng(seed)
    centres = rng.integers(0, 256, (n_centres, 32), dtype=np.uint8)
    desc, ids = [], []
    for c in centres:
        bits = np.tile(np.unpackbits(c), (per, 1))
        for row in bits:
            row[rng.choice(256, flips, replace=False)] ^= 1
        desc.append(np.packbits(bits, axis=1))
        ids.append(rng.integers(0, 5, per))
    return np.concatenate(desc), np.concatenate(ids)


def test_hamming_counts_differing_bits():
    a = np.zeros((1, 32), np.uint8)
    b = np.zeros((2, 32), np.uint8)
    b[0, 0] = 0b1011
    b[1] = 255
    assert hamming(a, b).tolist() == [[3, 256]]


def test_text_file_has_the_dbow2_format(tmp_path):
    desc, ids = _clustered_descriptors()
    vocab = build_vocabulary(desc, ids, k=3, levels=2, seed=0)
    path = write_dbow2_text(vocab, tmp_path / "voc.txt")
    text = path.read_text()
    lines = text.split("\n")
    assert lines[0] == "3 2 0 0"  # k L scoring(L1) weighting(TF-IDF)
    assert not text.endswith("\n")  # DBoW2's loader would read a trailing empty line as a node
    assert len(lines) - 1 == vocab.n_nodes - 1 == 3 + 9  # a full tree of k=3, L=2: every node but the root
    for i, line in enumerate(lines[1:], start=1):
        fields = line.split()
        assert len(fields) == 1 + 1 + 32 + 1  # parent, is_leaf, 32 descriptor bytes, weight
        parent, is_leaf = int(fields[0]), int(fields[1])
        assert 0 <= parent < i and is_leaf in (0, 1)
        assert all(0 <= int(b) <= 255 for b in fields[2:34])
        assert float(fields[34]) >= 0.0
        assert (is_leaf == 1) == (i > 3)  # depth-1 nodes inner, depth-2 nodes words
    back = read_dbow2_text(path)
    assert np.array_equal(back.parents, vocab.parents) and np.array_equal(back.descriptors, vocab.descriptors)
    assert np.array_equal(back.is_leaf, vocab.is_leaf)
    np.testing.assert_allclose(back.weights, vocab.weights, rtol=1e-5)
    words = words_of(vocab, desc)
    assert vocab.is_leaf[words].all()
    assert len(np.unique(words[:20])) <= 3  # one cluster's descriptors fall in few words


def test_small_input_makes_each_descriptor_a_word():
    desc, ids = _clustered_descriptors(n_centres=1, per=2)
    vocab = build_vocabulary(desc, ids, k=4, levels=3)
    assert vocab.n_nodes == 3 and vocab.is_leaf[1:].all()  # m <= k: one child per descriptor, leaves (DBoW2)
    assert np.array_equal(vocab.descriptors[1:], desc)


def test_reader_refuses_a_malformed_file(tmp_path):
    bad = tmp_path / "bad.txt"
    bad.write_text("8 3 0 0\n0 1 1 2 3 0.5")
    with pytest.raises(ValueError, match="32 bytes"):
        read_dbow2_text(bad)
    bad.write_text("30 3 0 0")
    with pytest.raises(ValueError, match="range"):
        read_dbow2_text(bad)


def test_committed_vocabulary_is_the_documented_one():
    vocab = read_dbow2_text(DEFAULT_VOCABULARY)
    assert (vocab.k, vocab.levels) == (8, 3)
    assert vocab.n_nodes - 1 == 584 and vocab.n_words == 512
    assert (vocab.weights[vocab.is_leaf] >= 0).all() and (vocab.weights[~vocab.is_leaf] == 0).all()


def test_orb_descriptors_of_a_textured_image():
    rng = np.random.default_rng(1)
    img = np.kron(rng.integers(0, 256, (30, 40), dtype=np.uint8), np.ones((8, 8), np.uint8))
    desc, ids = orb_descriptors([img, np.stack([img] * 3, axis=2)], n_features=200)
    assert desc.dtype == np.uint8 and desc.shape[1] == 32 and len(desc) > 50
    assert set(np.unique(ids)) == {0, 1}


def test_only_training_sequences_are_used():
    with pytest.raises(ValueError, match="training split"):
        next(training_frames(["office0"], per_sequence=1))
