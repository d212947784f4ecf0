"""slamcommon.formats.association: the TUM tools' greedy association (its brute-force checks against the tools'
sequential rule are in tests/eval/metrics/test_association.py, which also scores the judge's rules)."""

import numpy as np
import pytest

from slamcommon.errors import FormatError
from slamcommon.formats.association import associate_greedy


def test_greedy_takes_the_closest_pair_first_one_to_one():
    first = np.array([0.0, 0.01, 0.02, 1.0])
    second = np.array([0.012, 1.004])
    gi, si = associate_greedy(first, second, 0.02)
    assert gi.tolist() == [1, 3] and si.tolist() == [0, 1] and gi.dtype == si.dtype == np.int64
    gi, si = associate_greedy(first, second - 0.5, 0.02, offset=0.5)
    assert gi.tolist() == [1, 3] and si.tolist() == [0, 1]


@pytest.mark.parametrize("bad", [0.0, -1.0, float("nan"), float("inf")])
def test_a_bad_max_difference_is_refused(bad):
    with pytest.raises(FormatError, match="max_difference must be a positive number"):
        associate_greedy(np.zeros(1), np.zeros(1), bad)
