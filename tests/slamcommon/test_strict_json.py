"""slamcommon.strict_json: strict JSON for the records of both sides."""

import json

import numpy as np

from slamcommon.strict_json import json_ready


def test_nan_inf_and_numpy_become_strict_json():
    out = json_ready({"a": [np.float32(1.5), float("nan")], "b": {"c": np.int64(3), "d": float("-inf")},
                      "e": np.arange(2), 4: (1, 2)})
    assert out == {"a": [1.5, None], "b": {"c": 3, "d": None}, "e": [0, 1], "4": [1, 2]}
    assert type(out["b"]["c"]) is int
    json.dumps(out, allow_nan=False)
