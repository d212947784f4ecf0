"""A small DBoW2 vocabulary of ORB descriptors, built from SIMULATED TRAINING frames, for ORB-SLAM3.

ORB-SLAM3 needs a bag-of-words vocabulary (``ORBvoc.txt``, 139 MB, normally downloaded at run time, which cannot
work here). This module builds a small one ourselves, the way DBoW2 does: OpenCV ORB descriptors (256 bits, the same
rBRIEF pattern ORB-SLAM's extractor uses) of frames of the training split (``sim_envs.sequences``, split ``train``:
never a test sequence, never real data), clustered by hierarchical k-majority (k-medians under the Hamming distance:
k-means++ seeding, assignment to the nearest centre, each centre's bits the majority of its members') into a tree of
branching ``k`` and depth ``L``; the leaves are the words, weighted by their inverse document frequency
``log(N / n_i)`` over the N training frames (TF-IDF weighting, L1 scoring, as ORBvoc.txt).

The file is DBoW2's TEXT format, as ``TemplatedVocabulary::loadFromTextFile`` of ORB-SLAM3 reads it::

    k L scoring weighting                    e.g. "8 3 0 0" (0 0: L1-norm scoring, TF-IDF weighting)
    parent is_leaf d_0 d_1 ... d_31 weight   one line per node but the root, parents before children (node ids
                                             1, 2, ... in line order; the root is 0); d_i the descriptor's bytes

with no newline after the last line (the loader would read an empty line as one more node). Command::

    python -m thirdparty.orb_vocabulary --out thirdparty/vocabulary/orbvoc_train_k8l3.txt   # the committed file
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

DESCRIPTOR_BYTES = 32
DEFAULT_VOCABULARY = Path(__file__).with_name("vocabulary") / "orbvoc_train_k8l3.txt"
TRAINING_SEQUENCES: tuple[str, ...] = ("train_000", "train_001", "train_002")
L1_NORM, TF_IDF = 0, 0  # DBoW2's ScoringType.L1_NORM and WeightingType.TF_IDF
_POPCOUNT = np.array([bin(i).count("1") for i in range(256)], dtype=np.uint8)


@dataclass(frozen=True)
class Vocabulary:
    """A DBoW2 vocabulary tree. Node 0 is the root; nodes ``1..n-1`` in breadth-first order (a parent's id is
    smaller than its children's). parents: (n,) int (the root's: -1); descriptors: (n, 32) uint8 (the root's: 0);
    is_leaf: (n,) bool; weights: (n,) float64 (IDF of the words, 0 for inner nodes)."""

    k: int
    levels: int
    parents: np.ndarray
    descriptors: np.ndarray
    is_leaf: np.ndarray
    weights: np.ndarray

    @property
    def n_nodes(self) -> int:
        """Nodes including the root."""
        return int(len(self.parents))

    @property
    def n_words(self) -> int:
        """Leaves."""
        return int(self.is_leaf.sum())


def hamming(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(len(a), len(b)) int32 Hamming distances between rows of two (., 32) uint8 descriptor arrays."""
    return _POPCOUNT[np.bitwise_xor(a[:, None, :], b[None, :, :])].sum(axis=2, dtype=np.int32)


def _majority(desc: np.ndarray) -> np.ndarray:
    """The bitwise majority of (m, 32) uint8 descriptors (ties: 1, as DBoW2's FORB::meanValue)."""
    bits = np.unpackbits(desc, axis=1)
    return np.packbits(2 * bits.sum(axis=0, dtype=np.int64) >= len(desc))


def k_majority(desc: np.ndarray, k: int, rng: np.random.Generator, iterations: int = 20) -> tuple[np.ndarray,
                                                                                                    np.ndarray]:
    """Cluster (m, 32) uint8 descriptors into ``k`` groups: k-means++ seeding, then assignment / bitwise majority
    until the assignment is stable (at most ``iterations`` rounds). Returns (centres (k', 32), labels (m,)), k' <= k
    (centres left without members are dropped). With m <= k every descriptor is its own centre (as DBoW2)."""
    m = len(desc)
    if m <= k:
        return desc.copy(), np.arange(m)
    centres = [desc[int(rng.integers(m))]]
    dist = hamming(desc, centres[0][None]).reshape(-1).astype(np.float64)
    while len(centres) < k:
        p = dist**2
        if p.sum() == 0:
            break
        c = desc[int(rng.choice(m, p=p / p.sum()))]
        centres.append(c)
        dist = np.minimum(dist, hamming(desc, c[None]).reshape(-1))
    cent = np.stack(centres)
    labels = np.full(m, -1)
    for _ in range(iterations):
        new = hamming(desc, cent).argmin(axis=1)
        if np.array_equal(new, labels):
            break
        labels = new
        keep = [j for j in range(len(cent)) if np.any(labels == j)]
        cent = np.stack([_majority(desc[labels == j]) for j in keep])
        labels = np.searchsorted(np.asarray(keep), labels)
    labels = hamming(desc, cent).argmin(axis=1)
    return cent, labels


def build_vocabulary(descriptors: np.ndarray, image_ids: np.ndarray, k: int = 8, levels: int = 3,
                     seed: int = 0) -> Vocabulary:
    """The vocabulary tree of (m, 32) uint8 ``descriptors`` (``image_ids`` (m,): the training frame of each, for
    the IDF weights), branching ``k``, depth ``levels``, clustered by :func:`k_majority` with
    ``numpy.random.default_rng(seed)``. A node with at most one descriptor, or at depth ``levels``, is a word."""
    if not 2 <= k <= 20 or not 1 <= levels <= 10:
        raise ValueError(f"DBoW2 takes 2 <= k <= 20 and 1 <= L <= 10, got k={k}, L={levels}")
    descriptors = np.ascontiguousarray(descriptors, dtype=np.uint8)
    if descriptors.ndim != 2 or descriptors.shape[1] != DESCRIPTOR_BYTES or len(descriptors) == 0:
        raise ValueError(f"descriptors must be a non-empty (m, 32) uint8 array, got {descriptors.shape}")
    rng = np.random.default_rng(seed)
    parents, descs, depth = [-1], [np.zeros(DESCRIPTOR_BYTES, np.uint8)], [0]
    members: list[np.ndarray] = [np.arange(len(descriptors))]
    children: list[list[int]] = [[]]
    node = 0
    while node < len(parents):  # breadth first: nodes are numbered in the order the loader numbers them
        idx = members[node]
        if depth[node] < levels and (node == 0 or len(idx) > 1):
            cent, labels = k_majority(descriptors[idx], k, rng)
            for j, c in enumerate(cent):
                parents.append(node)
                descs.append(c)
                depth.append(depth[node] + 1)
                members.append(idx[labels == j])
                children.append([])
                children[node].append(len(parents) - 1)
        node += 1
    is_leaf = np.array([not c for c in children])
    vocab = Vocabulary(k, levels, np.array(parents), np.stack(descs), is_leaf, np.zeros(len(parents)))
    words = words_of(vocab, descriptors)
    n_images = len(np.unique(image_ids))
    weights = np.zeros(len(parents))
    for w in np.flatnonzero(is_leaf):
        n_i = len(np.unique(image_ids[words == w]))
        weights[w] = math.log(n_images / n_i) if n_i else 0.0
    return Vocabulary(k, levels, vocab.parents, vocab.descriptors, is_leaf, weights)


def words_of(vocab: Vocabulary, descriptors: np.ndarray) -> np.ndarray:
    """The word (leaf node id) of each descriptor: from the root, the nearest child until a leaf (as DBoW2's
    ``transform``; ties: the first child)."""
    lists: dict[int, list[int]] = {}
    for n in range(1, vocab.n_nodes):
        lists.setdefault(int(vocab.parents[n]), []).append(n)
    kids = {p: np.asarray(c) for p, c in lists.items()}
    at = np.zeros(len(descriptors), dtype=np.int64)
    while True:
        inner = np.flatnonzero(~vocab.is_leaf[at])
        if len(inner) == 0:
            return at
        for p in np.unique(at[inner]):
            sel = inner[at[inner] == p]
            c = kids[int(p)]
            at[sel] = c[hamming(descriptors[sel], vocab.descriptors[c]).argmin(axis=1)]


def write_dbow2_text(vocab: Vocabulary, path: str | Path) -> Path:
    """Write ``vocab`` in DBoW2's text format (module docstring); returns the path."""
    lines = [f"{vocab.k} {vocab.levels} {L1_NORM} {TF_IDF}"]
    for n in range(1, vocab.n_nodes):
        d = " ".join(str(int(b)) for b in vocab.descriptors[n])
        lines.append(f"{int(vocab.parents[n])} {int(vocab.is_leaf[n])} {d} {vocab.weights[n]:.6g}")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("\n".join(lines))  # no newline after the last node: DBoW2's loader would add an empty node
    return path


def read_dbow2_text(path: str | Path) -> Vocabulary:
    """Read a DBoW2 text vocabulary, checking its format (ValueError naming the line otherwise)."""
    text = Path(path).read_text()
    rows = text.split("\n")
    head = rows[0].split()
    if len(head) != 4:
        raise ValueError(f"{path}: the header must be 'k L scoring weighting', got {rows[0]!r}")
    k, levels, scoring, weighting = (int(v) for v in head)
    if not (0 <= k <= 20 and 1 <= levels <= 10 and 0 <= scoring <= 5 and 0 <= weighting <= 3):
        raise ValueError(f"{path}: header out of DBoW2's range: {rows[0]!r}")
    parents, descs, leaf, weights = [-1], [np.zeros(DESCRIPTOR_BYTES, np.uint8)], [False], [0.0]
    for i, row in enumerate(rows[1:], start=2):
        f = row.split()
        if len(f) != 3 + DESCRIPTOR_BYTES:
            raise ValueError(f"{path}:{i}: a node line has parent, is_leaf, 32 bytes and a weight, got {len(f)} fields")
        p, is_leaf = int(f[0]), int(f[1])
        if not 0 <= p < len(parents) or is_leaf not in (0, 1) or leaf[p]:
            raise ValueError(f"{path}:{i}: parent {p} is not an earlier inner node, or is_leaf {is_leaf} not 0/1")
        b = np.array([int(v) for v in f[2:-1]])
        if b.min() < 0 or b.max() > 255:
            raise ValueError(f"{path}:{i}: descriptor bytes must be 0..255")
        parents.append(p)
        descs.append(b.astype(np.uint8))
        leaf.append(bool(is_leaf))
        weights.append(float(f[-1]))
    return Vocabulary(k, levels, np.array(parents), np.stack(descs), np.array(leaf), np.array(weights))


def orb_descriptors(images: Iterable[np.ndarray], n_features: int = 1000,
                    fast_threshold: int = 7) -> tuple[np.ndarray, np.ndarray]:
    """OpenCV ORB descriptors of RGB (or grey) uint8 images (``n_features`` per image, scale factor 1.2, 8 levels,
    as ORB-SLAM's extractor; FAST threshold 7, ORB-SLAM's fallback threshold for low-contrast cells, since the
    simulated rooms are low in contrast). Returns (descriptors (m, 32) uint8, image index (m,))."""
    import cv2

    orb = cv2.ORB_create(nfeatures=n_features, scaleFactor=1.2, nlevels=8, fastThreshold=fast_threshold)
    all_desc, ids = [], []
    for i, img in enumerate(images):
        grey = cv2.cvtColor(img, cv2.COLOR_RGB2GRAY) if img.ndim == 3 else img
        _, d = orb.detectAndCompute(grey, None)
        if d is not None and len(d):
            all_desc.append(d)
            ids.append(np.full(len(d), i))
    if not all_desc:
        return np.zeros((0, DESCRIPTOR_BYTES), np.uint8), np.zeros(0, np.int64)
    return np.concatenate(all_desc), np.concatenate(ids)


def training_frames(sequences: Sequence[str] = TRAINING_SEQUENCES, per_sequence: int = 30,
                    camera: str = "kinect") -> Iterator[np.ndarray]:
    """``per_sequence`` evenly spaced RGB frames of each sequence seen through ``camera`` (a camera preset of
    :mod:`sim_envs.sensor.camera_effects`). Only sequences of the TRAINING split: ValueError for any other."""
    from dataclasses import replace

    from sim_envs.sequences import get_sequence
    from sim_envs.sources.simsource import SimulatedSequence

    for name in sequences:
        spec = get_sequence(name)
        if spec.split != "train":
            raise ValueError(f"{name!r} is not a sequence of the training split; the vocabulary is built from "
                             "training frames only (test sequences and real data are test data)")
        # the sequence as the suites name it, ``name@camera`` (the world reads the camera preset from the spec)
        source = SimulatedSequence(replace(spec, name=f"{name}@{camera}", camera_effects=camera))
        n = len(source)
        for i in np.linspace(0, n - 1, per_sequence).round().astype(int):
            yield source.frame(int(i)).rgb


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m thirdparty.orb_vocabulary``: build the vocabulary from training frames and write it."""
    ap = argparse.ArgumentParser(prog="python -m thirdparty.orb_vocabulary", description=__doc__.split("\n")[0])
    ap.add_argument("--sequences", nargs="+", default=list(TRAINING_SEQUENCES), help="training sequences")
    ap.add_argument("--frames", type=int, default=30, help="frames per sequence, evenly spaced")
    ap.add_argument("--camera", default="kinect", help="camera preset the frames are seen through")
    ap.add_argument("--features", type=int, default=1000, help="ORB features per frame")
    ap.add_argument("--fast-threshold", type=int, default=7, help="FAST threshold of the ORB detector")
    ap.add_argument("--k", type=int, default=8, help="branching factor")
    ap.add_argument("--levels", type=int, default=3, help="depth L of the tree")
    ap.add_argument("--seed", type=int, default=0, help="seed of the k-means++ draws")
    ap.add_argument("--out", type=Path, default=DEFAULT_VOCABULARY, help="output file (DBoW2 text)")
    args = ap.parse_args(argv)
    frames = list(training_frames(args.sequences, args.frames, args.camera))
    desc, ids = orb_descriptors(frames, args.features, args.fast_threshold)
    vocab = build_vocabulary(desc, ids, args.k, args.levels, args.seed)
    path = write_dbow2_text(vocab, args.out)
    print(f"{path}: {vocab.n_nodes - 1} nodes, {vocab.n_words} words, from {len(desc)} descriptors of "
          f"{len(frames)} frames of {', '.join(args.sequences)} @{args.camera}; {path.stat().st_size} bytes")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
