"""The C allocator's side of a flat resident memory (receiver/_malloc.py): freed chunk-sized arrays that
glibc keeps on its heap go back to the kernel when the chunk loop trims."""
import os
import subprocess
import sys

import pytest

from receiver import _malloc

pytestmark = pytest.mark.skipif(_malloc._libc() is None, reason="needs glibc's malloc")

#: a fresh process: the pattern of a chunk loop (an 8-MB array allocated, written and freed, twice, with a
#: small block allocated in between), then the anonymous memory still held (MB) before and after trim()
PROBE = r"""
import re
from receiver import _malloc
configured = _malloc.configure()
import numpy as np
def anon():
    return int(re.search(r"RssAnon:\s+(\d+)", open("/proc/self/status").read()).group(1)) / 1024
base = anon()
keep = []
for _ in range(2):
    a = np.ones(1 << 20, np.complex64)
    keep.append(np.ones(100))
    del a
held = anon() - base
trimmed = _malloc.trim()
print(configured, trimmed, held, anon() - base)
"""


def _probe(env_extra: dict):
    env = {k: v for k, v in os.environ.items() if not k.startswith("MALLOC_") and k != "GNSSRX_MALLOC"}
    env.update(env_extra)
    out = subprocess.run([sys.executable, "-c", PROBE], capture_output=True, text=True, env=env, check=True)
    c, t, held, after = out.stdout.split()
    return c == "True", t == "True", float(held), float(after)


def test_trim_hands_freed_heap_memory_back():
    configured, trimmed, held, after = _probe({})
    assert configured and trimmed
    assert held > 6.0            # glibc's rising mapping threshold put the second array on the heap and kept it
    assert after < 2.0           # trim() returned it


def test_default_allocator_keeps_it():
    configured, trimmed, held, after = _probe({"GNSSRX_MALLOC": "default"})
    assert not configured and not trimmed
    assert after > 6.0


def test_arena_max_from_the_environment_wins():
    configured, trimmed, _, after = _probe({"MALLOC_ARENA_MAX": "4"})
    assert not configured and trimmed
    assert after < 2.0
