"""The global model's storage and key index: rows appended, found by key, compacted (in place or in any order) and
re-indexed; growth keeps the rows."""

from __future__ import annotations

import numpy as np

from cnnslam.model.surfel_store import SurfelStore


def _filled(n: int) -> SurfelStore:
    store = SurfelStore(num_classes=3)
    rows = store.append(np.arange(n, dtype=np.int64) * 10)
    store.columns["radius"][rows] = np.arange(n)
    store.evidence[rows, 1] = np.arange(n)
    return store


def test_append_grows_and_indexes_by_key():
    store = _filled(40)  # past the initial capacity of 16: grown twice
    assert len(store) == 40 and store.columns["radius"].shape[0] >= 40
    assert np.array_equal(store.column("radius"), np.arange(40))
    assert store.ids_of_keys(np.array([0, 70, 75, 390, 400])).tolist() == [0, 7, -1, 39, -1]
    later = store.append(np.array([5, 395]))
    assert (later.start, later.stop) == (40, 42) and store.ids_of_keys(np.array([5, 395])).tolist() == [40, 41]
    assert not store.live_evidence()[40:].any()


def test_compact_in_place_or_in_any_order_then_reindex():
    store = _filled(10)
    store.compact(np.array([1, 4, 9]))
    store.reindex()
    assert np.array_equal(store.column("radius"), [1, 4, 9]) and np.array_equal(store.live_evidence()[:, 1], [1, 4, 9])
    assert store.ids_of_keys(np.array([10, 40, 90, 20])).tolist() == [0, 1, 2, -1]
    store.compact(np.array([2, 0]))  # not increasing: copied
    store.reindex()
    assert np.array_equal(store.column("radius"), [9, 1]) and store.ids_of_keys(np.array([90, 10])).tolist() == [0, 1]


def test_key_runs_put_the_strongest_anchor_first():
    store = SurfelStore(num_classes=1)
    rows = store.append(np.array([1, 2, 3]))
    store.columns["key"][rows] = [7, 5, 7]  # two rows now share key 7 (as after a re-placement)
    store.columns["anchor_weight"][rows] = [1.0, 1.0, 3.0]
    order, first = store.key_runs()
    assert order.tolist() == [1, 2, 0] and first.tolist() == [True, True, False]  # keys 5 | 7, 7
    store.gather(order[first], {"radius": (np.array([1]), np.array([9.0])), "evidence": (np.array([0]), 1.0)})
    store.reindex()
    assert len(store) == 2 and store.ids_of_keys(np.array([5, 7])).tolist() == [0, 1]
    assert store.column("radius").tolist() == [0.0, 9.0] and store.live_evidence()[:, 0].tolist() == [1.0, 0.0]
    assert store.column("anchor_weight").tolist() == [1.0, 3.0]  # the strongest anchor led its run


def test_drop_index_forgets_the_keys_until_reindex_and_gather_copies_by_component():
    store = SurfelStore(num_classes=3)
    rows = store.append(np.array([4, 8, 9]))
    store.columns["position"][rows] = np.arange(9, dtype=np.float32).reshape(3, 3)
    store.evidence[rows] = np.arange(9, dtype=np.float32).reshape(3, 3) + 10
    store.drop_index()
    assert store.ids_of_keys(np.array([4, 8, 9])).tolist() == [-1, -1, -1]
    store.gather(np.array([2, 0]), {"evidence": (np.array([1]), np.array([[7.0, 8.0, 9.0]]))})
    store.reindex()
    assert store.ids_of_keys(np.array([4, 9, 8])).tolist() == [1, 0, -1]
    assert store.column("position").tolist() == [[6, 7, 8], [0, 1, 2]]
    assert store.live_evidence().tolist() == [[16, 17, 18], [7, 8, 9]]


def test_remove_rows_keeps_the_index_a_re_sort_would_build():
    """After appends in random key order and removals, the kept index equals the one sorted again from the keys (the
    renumbered ids included); where the kept keys repeat, or the index was dropped, it is dropped for a rebuild."""
    rng = np.random.default_rng(5)
    store = SurfelStore(num_classes=2)
    for _ in range(30):
        fresh = np.setdiff1d(rng.choice(5000, size=40, replace=False), store.column("key"))
        store.append(fresh)  # sorted, unique, none held
        keep = np.flatnonzero(rng.random(len(store)) > 0.1)
        old_keys = store.column("key").copy()
        assert store.remove_rows(keep)
        assert np.array_equal(store.column("key"), old_keys[keep])
        kept_keys, kept_ids = store._sorted_keys.copy(), store._sorted_ids.copy()
        store.reindex()
        assert np.array_equal(kept_keys, store._sorted_keys) and np.array_equal(kept_ids, store._sorted_ids)
        probe = rng.choice(5000, size=100)
        expected = [int(np.flatnonzero(store.column("key") == k)[0]) if k in store.column("key") else -1
                    for k in probe]
        assert store.ids_of_keys(probe).tolist() == expected
    store.columns["key"][1] = store.columns["key"][0]  # two rows share a key (as after a re-placement)
    store.reindex()
    assert not store.remove_rows(np.arange(len(store) - 1))  # their order is the caller's: rebuild
    assert store.ids_of_keys(store.column("key")[:3]).tolist() == [-1, -1, -1]
    store.reindex()
    store.drop_index()
    assert not store.remove_rows(np.arange(len(store) - 1))  # no complete index to keep
