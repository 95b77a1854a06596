"""runtime/memory.py: freed large arrays go back to the system (Linux, glibc)."""

from __future__ import annotations

import subprocess
import sys

import pytest

CHILD = """
import sys
import numpy as np
from warp_spt.runtime.memory import map_large_allocations
if sys.argv[1] == "1":
    map_large_allocations()
def rss_mb():
    for line in open("/proc/self/status"):
        if line.startswith("VmRSS"):
            return int(line.split()[1]) / 1024
base = rss_mb()
a = np.ones(24 << 17)          # 24 MiB, freed: glibc's dynamic threshold rises to 24 MiB (at most 32)
del a
b = np.ones(16 << 17)          # 16 MiB from the heap now, unless the threshold is fixed
c = np.ones(1 << 17)           # 1 MiB above it
del b                          # not at the heap's top: kept by the process
print(rss_mb() - base)
"""


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's malloc only")
def test_a_freed_large_array_is_returned_to_the_system():
    kept = {flag: float(subprocess.run([sys.executable, "-c", CHILD, flag], capture_output=True, text=True,
                                       check=True).stdout) for flag in ("0", "1")}
    # Without the fixed threshold the freed 16 MiB usually stay resident: that is what makes this test
    # able to fail. Where the allocator returns them anyway (seen in some runs: where the heap could not
    # grow in place, glibc maps it elsewhere), there is nothing to tell apart.
    if kept["0"] <= 12:
        pytest.skip(f"this allocator returned the freed block without the fix too ({kept})")
    assert kept["1"] < 4, kept
