"""A numba cache write that fails (a full disk, a file-size limit) does not end the run: the function just
compiled is used uncached (receiver/_numba_start.py).  Without the guard numba raises the OSError."""
import subprocess
import sys
import textwrap

import pytest

CHILD = textwrap.dedent("""
    import resource, sys
    resource.setrlimit(resource.RLIMIT_FSIZE, (1, 1))      # any cache file is too large
    sys.path.insert(0, {mod_dir!r})
    from receiver import _numba_start
    if {guard}:
        assert _numba_start.tolerate_cache_write_errors()
    import fresh_kernel
    print(fresh_kernel.twice(21))
""")


@pytest.mark.parametrize("guard", [True, False])
def test_a_failed_cache_write_leaves_the_function_usable(tmp_path, guard):
    (tmp_path / "fresh_kernel.py").write_text(
        "import numba\n\n@numba.njit(cache=True)\ndef twice(x):\n    return 2 * x\n")
    env = {"NUMBA_CACHE_DIR": str(tmp_path / "cache"), "PATH": "/usr/bin:/bin"}
    r = subprocess.run([sys.executable, "-c", CHILD.format(mod_dir=str(tmp_path), guard=guard)],
                       capture_output=True, text=True, env=env, timeout=120)
    if guard:
        assert r.returncode == 0 and r.stdout.strip() == "42", r.stderr[-1500:]
    else:
        assert r.returncode != 0 and "File too large" in r.stderr
