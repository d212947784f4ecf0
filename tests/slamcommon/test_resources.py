"""Peak resident memory of this process."""

import numpy as np

from slamcommon.resources import peak_resident_mib


def test_the_peak_grows_by_what_the_process_touches():
    before = peak_resident_mib()
    block = np.ones(64 * 1024 * 1024 // 8)  # 64 MiB written, so resident
    after = peak_resident_mib()
    assert block.sum() == block.size
    assert after >= before and after >= 64  # the peak holds the block (and the interpreter around it)
