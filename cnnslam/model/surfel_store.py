"""The global model's storage and index, apart from fusion (as DPVO keeps its patch graph apart from the algorithm):
one row per surfel in columns of fixed types, grown by 1.25x, compacted in place, and a sorted index of the rows'
voxel keys for the hash lookup of fusion's step 4 (:mod:`cnnslam.model.global_model`). What the rows mean and how they
are
computed is fusion's business; here rows are only stored, found by key, removed and re-indexed.

Columns (:data:`SURFEL_COLUMNS`): position, normal (world, float32), colour (RGB 0..255 float32), radius (m), weight
W = sum alpha / sigma_d^2, confidence c = sum alpha, n_obs (frames merged in), anchor (key-frame id, -1 = none) and
anchor_weight, first_seen (integration counter), misses (free-space test), key (int64 voxel key); and the
label evidence L (N, C) float32 of :mod:`cnnslam.model.label_fusion`.
"""

from __future__ import annotations

import numpy as np

from cnnslam.errors import CnnSlamError
from cnnslam.model.surfel_kernels import compact_1d, compact_2d

SURFEL_COLUMNS: dict[str, tuple[type, tuple[int, ...]]] = {
    "position": (np.float32, (3,)),
    "normal": (np.float32, (3,)),
    "colour": (np.float32, (3,)),
    "radius": (np.float32, ()),
    "weight": (np.float32, ()),
    "confidence": (np.float32, ()),
    "n_obs": (np.uint32, ()),
    "anchor": (np.int32, ()),
    "anchor_weight": (np.float32, ()),
    "first_seen": (np.int32, ()),
    "misses": (np.uint16, ()),
    "key": (np.int64, ()),
}
_INITIAL_CAPACITY = 16


class SurfelStore:
    """Surfel rows (:data:`SURFEL_COLUMNS` and the label evidence of ``num_classes`` classes) and their key index.

    ``columns[name]`` and ``evidence`` are the allocated arrays (capacity rows; rows ``[:len(store)]`` are live), so
    fusion updates rows in place; :meth:`column` is the live view. The index (:meth:`ids_of_keys`) is kept by
    :meth:`append` and rebuilt by :meth:`reindex`.
    """

    def __init__(self, num_classes: int) -> None:
        self.columns: dict[str, np.ndarray] = {name: np.zeros((_INITIAL_CAPACITY, *shape), dtype)
                                               for name, (dtype, shape) in SURFEL_COLUMNS.items()}
        self.evidence = np.zeros((_INITIAL_CAPACITY, int(num_classes)), np.float32)
        self._size = 0
        self._sorted_keys = np.zeros(0, np.int64)
        self._sorted_ids = np.zeros(0, np.int64)

    def __len__(self) -> int:
        return self._size

    @property
    def nbytes(self) -> int:
        """Bytes held by the arrays (allocated capacity, index included)."""
        return (sum(a.nbytes for a in self.columns.values()) + self.evidence.nbytes + self._sorted_keys.nbytes
                + self._sorted_ids.nbytes)

    def column(self, name: str) -> np.ndarray:
        """The live rows of a column (a view)."""
        return self.columns[name][: self._size]

    def live_evidence(self) -> np.ndarray:
        """The live rows of the label evidence (a view)."""
        return self.evidence[: self._size]

    def _reserve(self, extra: int) -> None:
        need = self._size + extra
        cap = self.columns["position"].shape[0]
        if need <= cap:
            return
        new_cap = max(need, cap + cap // 4)  # 1.25x: a long episode's model is hundreds of MB; slack is memory
        for name, arr in self.columns.items():
            grown = np.zeros((new_cap, *arr.shape[1:]), arr.dtype)
            grown[: self._size] = arr[: self._size]
            self.columns[name] = grown
        evidence = np.zeros((new_cap, self.evidence.shape[1]), np.float32)
        evidence[: self._size] = self.evidence[: self._size]
        self.evidence = evidence

    def append(self, keys: np.ndarray) -> slice:
        """Room for ``keys.size`` new rows with these voxel keys (sorted, unique, none held yet), indexed; returns the
        slice of the new rows, whose other columns and evidence the caller fills (evidence starts at zero)."""
        keys = np.asarray(keys, dtype=np.int64)
        k = keys.size
        self._reserve(k)
        rows = slice(self._size, self._size + k)
        self.columns["key"][rows] = keys
        self.evidence[rows] = 0.0
        new_ids = np.arange(self._size, self._size + k, dtype=np.int64)
        self._size += k
        at = np.searchsorted(self._sorted_keys, keys)
        self._sorted_keys = np.insert(self._sorted_keys, at, keys)
        self._sorted_ids = np.insert(self._sorted_ids, at, new_ids)
        return rows

    def ids_of_keys(self, keys: np.ndarray) -> np.ndarray:
        """(K,) int64 id of the row holding each voxel key, -1 where none does."""
        out = np.full(keys.shape, -1, np.int64)
        if self._sorted_keys.size:
            pos = np.minimum(np.searchsorted(self._sorted_keys, keys), self._sorted_keys.size - 1)
            found = self._sorted_keys[pos] == keys
            out[found] = self._sorted_ids[pos[found]]
        return out

    def compact(self, keep: np.ndarray) -> None:
        """Keep the rows ``keep`` (ids, in this order) and drop the others; the index must be rebuilt
        (:meth:`reindex`). Increasing ``keep`` (the usual removal) moves rows in place without copies."""
        keep = np.asarray(keep, dtype=np.int64)
        if keep.size > 1 and not bool(np.all(keep[1:] > keep[:-1])):
            for arr in (*self.columns.values(), self.evidence):
                arr[: keep.size] = arr[keep]
        else:
            for arr in (*self.columns.values(), self.evidence):
                (compact_1d if arr.ndim == 1 else compact_2d)(arr, keep)
        self._size = keep.size

    def remove_rows(self, keep: np.ndarray) -> bool:
        """:meth:`compact` for a removal (``keep`` increasing ids) that also keeps the key index: the removed rows'
        entries are dropped from it and the others renumbered, instead of sorting the keys again. Returns False, with
        the index dropped for the caller to rebuild, where it cannot be kept: the index was not complete, ``keep`` is
        not increasing, or a key is held by several kept rows (their order in the index is the caller's:
        ``GlobalModel`` orders them by anchor weight)."""
        keep = np.asarray(keep, dtype=np.int64)
        n_old = self._size
        keepable = self._sorted_keys.size == n_old and (keep.size < 2 or bool(np.all(keep[1:] > keep[:-1])))
        self.compact(keep)
        if keepable:
            renumber = np.full(n_old, -1, np.int64)
            renumber[keep] = np.arange(keep.size, dtype=np.int64)
            ids = renumber[self._sorted_ids]
            live = ids >= 0
            keys = self._sorted_keys[live]
            if not bool(np.any(keys[1:] == keys[:-1])):
                self._sorted_keys, self._sorted_ids = keys, ids[live]
                return True
        self.drop_index()
        return False

    def gather(self, ids: np.ndarray, overrides: dict[str, tuple[np.ndarray, np.ndarray]] | None = None) -> None:
        """Make live row j the current row ``ids[j]`` (j < len(ids)) and drop the rest, one column at a time (so the
        transient memory is one column, not the store); ``overrides[name] = (js, values)`` then sets rows ``js`` of
        column ``name`` (``"evidence"``: the label evidence) to ``values``. The index must be rebuilt
        (:meth:`reindex`)."""
        overrides = overrides or {}
        unknown = sorted(set(overrides) - {*self.columns, "evidence"})
        if unknown:
            raise CnnSlamError(f"no surfel column {unknown}; columns: {', '.join(self.columns)}, evidence")
        ids = np.asarray(ids, dtype=np.int64)
        for name, arr in (*self.columns.items(), ("evidence", self.evidence)):
            js, values = overrides.get(name, (None, None))
            for j in range(arr.shape[1]) if arr.ndim == 2 else (None,):  # one component at a time: the transient
                target = arr if j is None else arr[:, j]                  # is one (N,) copy, not (N, 3) or (N, C)
                column = target[ids]
                if js is not None:  # the values as they would be assigned to the whole rows
                    column[js] = values if j is None else np.broadcast_to(values, (len(js), arr.shape[1]))[:, j]
                target[: ids.size] = column
                del column
        self._size = ids.size

    def key_runs(self) -> tuple[np.ndarray, np.ndarray]:
        """The rows sorted by key, the strongest anchor (``anchor_weight``) first among rows sharing one: (order,
        ``first`` (N,) bool: True where a run of one key starts in ``order``)."""
        keys = self.column("key")
        order = np.lexsort((-self.column("anchor_weight"), keys))
        sk = keys[order]
        first = np.empty(sk.size, bool)
        first[:1] = True
        np.not_equal(sk[1:], sk[:-1], out=first[1:])
        return order, first

    def drop_index(self) -> None:
        """Release the key index (before a re-hash that rebuilds it: the old index need not live beside the
        re-hash's temporaries); :meth:`ids_of_keys` finds nothing until :meth:`reindex`."""
        self._sorted_keys = np.zeros(0, np.int64)
        self._sorted_ids = np.zeros(0, np.int64)

    def reindex(self, order: np.ndarray | None = None) -> None:
        """Rebuild the key index from the key column; ``order``: the rows already sorted by key (else sorted here,
        stable)."""
        keys = self.column("key")
        if order is None:
            order = np.argsort(keys, kind="stable")
        self._sorted_keys = keys[order]
        self._sorted_ids = np.asarray(order).astype(np.int64, copy=False)
