"""Parallel tracking (receiver/threads.py): the run file does not depend on the thread count.

Two runs of the first seconds of the reference recording (assisted: fixes within ~2 s), one thread and
two threads, compared bit for bit with scripts/tools/compare_runs.py (every dataset and attribute except the
wall-clock ones)."""
import sys

import pytest

from repo_paths import ROOT, TOKYO_NAV, TOKYO_REC
from receiver import threads


@pytest.fixture(autouse=True)
def _restore_threads():
    yield
    threads.set_threads(None)


def test_map_ordered_keeps_the_order_and_uses_the_pool():
    import threading
    threads.set_threads(2)
    names = threads.map_ordered(lambda i: (i, threading.current_thread().name), list(range(8)))
    assert [i for i, _ in names] == list(range(8))
    assert all(n.startswith("gnssrx-track") for _, n in names)
    threads.set_threads(1)
    assert threads.map_ordered(lambda i: threading.current_thread().name, [0, 1]) == \
        [threading.current_thread().name] * 2


def test_submit_ordered_and_serial_threads():
    """submit_ordered returns at once and gives the list in order; a thread marked serial_here (the
    read-ahead) runs map_ordered's items itself, other threads still use the pool."""
    import threading
    from concurrent.futures import ThreadPoolExecutor
    threads.set_threads(2)
    gate = threading.Event()
    done = []

    def item(i):
        ok = gate.wait(30)
        done.append(i)
        return ok, i
    job = threads.submit_ordered(item, list(range(6)))
    assert done == []                           # returned while every item still waits on the gate
    gate.set()
    assert job() == [(True, i) for i in range(6)]
    with ThreadPoolExecutor(1, initializer=threads.serial_here) as ex:
        me, names = ex.submit(lambda: (threading.current_thread().name,
                                       threads.map_ordered(lambda i: threading.current_thread().name,
                                                           [0, 1, 2]))).result()
    assert names == [me] * 3 and not me.startswith("gnssrx-track")
    assert all(n.startswith("gnssrx-track") for n in threads.map_ordered(
        lambda i: threading.current_thread().name, [0, 1, 2]))


def test_thread_count_from_the_environment(monkeypatch):
    threads.set_threads(None)
    monkeypatch.setenv("GNSSRX_THREADS", "3")
    assert threads.threads() == 3
    monkeypatch.setenv("GNSSRX_THREADS", "")
    assert threads.threads() == threads.cores()
    threads.set_threads(1)
    assert threads.threads() == 1
    with pytest.raises(ValueError):
        threads.set_threads(-1)


@pytest.mark.parametrize("variant", ["pll", "kf"])
def test_run_files_are_bit_identical_whatever_the_thread_count(tmp_path, variant):
    if not (TOKYO_REC.exists() and TOKYO_NAV.exists()):
        pytest.skip("../shared/data reference recording absent")
    from receiver.schema import load_receiver_config
    from receiver.pipeline import run
    from receiver.runfile.compare import compare_h5
    out = {}
    for n in (1, 2):
        threads.set_threads(n)
        out[n] = tmp_path / f"t{n}" / "run.h5"
        out[n].parent.mkdir()
        cfg = load_receiver_config(ROOT / "configs" / "gpssim_static_tokyo.yaml",
                                   [("input.path", str(TOKYO_REC)), ("output.path", str(out[n])),
                                    ("navigation.ephemeris", str(TOKYO_NAV)), ("input.duration_s", 2.5),
                                    ("tracking.carrier.variant", variant),
                                    ("acquisition.prns", [10, 12, 13, 15, 18, 19, 23, 24, 25, 32])])
        s = run(cfg, quiet=True, log=lambda *a: None)
        assert len(s.tracked) >= 8 and s.n_fixes > 0
    diffs = []
    compare_h5(out[1], out[2], diffs)
    assert diffs == [], diffs[:5]


def test_cli_threads_option_rejects_a_negative_count(tmp_path):
    from click.testing import CliRunner

    from receiver.cli import main
    r = CliRunner().invoke(main, ["run", str(ROOT / "configs" / "gpssim_static_tokyo.yaml"), "--threads", "-1",
                                  "-o", str(tmp_path / "x.h5")])
    assert r.exit_code == 2 and "--threads" in r.output
    assert not (tmp_path / "x.h5").exists()


def test_background_writer_keeps_the_order_and_reports_write_errors():
    import numpy as np

    from receiver.errors import UserError
    from receiver.runfile.background import BackgroundWriter

    class Fake:
        def __init__(self):
            self.calls, self.closed, self.fail = [], None, False

        def append_channel(self, prn, recs):
            if self.fail:
                raise UserError("disk full")
            self.calls.append(("ch", prn, len(recs)))

        def append_fixes(self, rows):
            self.calls.append(("fix", len(rows)))

        def append_observables(self, rows):
            self.calls.append(("obs", len(rows)))

        def set_attrs(self, group, attrs):
            self.calls.append(("attrs", group))

        def close(self, ok=True):
            self.closed = ok

    f = Fake()
    w = BackgroundWriter(f)
    for k in range(3):
        w.append_channel(5, np.zeros(10))
        w.append_fixes(np.zeros(5))            # gathered: fewer than TABLE_ROWS rows
    w.append_observables(np.zeros(BackgroundWriter.TABLE_ROWS))   # a full block goes at once
    w.set_attrs("/", {})                       # a synchronous call waits for the appends
    assert f.calls == [("ch", 5, 10)] * 3 + [("obs", BackgroundWriter.TABLE_ROWS), ("fix", 15), ("attrs", "/")]
    f.fail = True
    w.append_channel(5, np.zeros(1))
    with pytest.raises(UserError, match="disk full"):
        w.flush()
    w.close(ok=False)
    assert f.closed is False
    f2 = Fake()
    w2 = BackgroundWriter(f2)
    w2.append_fixes(np.zeros(3))
    w2.close()
    assert f2.calls == [("fix", 3)] and f2.closed is True


def test_read_ahead_gives_the_samples_of_plain_reads():
    """source.prefetch.PrefetchingReader: chunks read ahead (conditioning state copied) equal plain sequential
    reads, also when another read (a search elsewhere) comes in between and the read-ahead is discarded."""
    if not TOKYO_REC.exists():
        pytest.skip("../shared/data reference recording absent")
    import numpy as np

    from receiver.schema import load_receiver_config
    from receiver.pipeline import open_input
    from receiver.source.prefetch import PrefetchingReader
    cfg = load_receiver_config(ROOT / "configs" / "gpssim_static_tokyo.yaml", [("input.path", str(TOKYO_REC))])
    plain, ahead = open_input(cfg), PrefetchingReader(open_input(cfg))
    assert ahead._ok and hasattr(ahead._r, "canceller")          # the conditioning stage is outermost
    n, step = 70000, 60000
    try:
        for k in range(6):
            s = plain.first + k * step
            if k == 3:                       # a search elsewhere moves the filter stream of both
                assert np.array_equal(plain.read(s + 10 ** 6, 5000), ahead.read(s + 10 ** 6, 5000))
            assert np.array_equal(plain.read(s, n), ahead.chunk(s, n, s + step))
    finally:
        ahead.close()
    assert ahead.ahead_used == 4             # chunks 1, 2, 4, 5 came from the read-ahead; 3 was read again


def test_background_writer_queues_acquisition_tables_from_a_snapshot():
    """write_acquisition does not wait for the pending appends; what it writes is the results as they
    were at the call, in the order of the calls."""
    import threading

    import numpy as np

    from receiver.acquisition import AcqResult
    from receiver.runfile.background import BackgroundWriter

    gate = threading.Event()

    class Slow:
        def __init__(self):
            self.calls = []

        def append_channel(self, prn, recs):
            gate.wait(10)
            self.calls.append(("ch", prn))

        def write_acquisition(self, results, attrs=None):
            self.calls.append(("acq", [(r.prn, r.detected) for r in results], attrs["fs"]))

        def close(self, ok=True):
            pass

    f = Slow()
    w = BackgroundWriter(f)
    w.append_channel(3, np.zeros(2))                  # held by the gate
    res = [AcqResult(7, True, 100.0, 5.0, 0, 2.0, 30.0, 40.0)]
    w.write_acquisition(res, {"fs": 2.6e6})           # returns although the append is pending
    res[0].detected = False                           # (the caller's later changes are not written)
    assert f.calls == []
    gate.set()
    w.close()
    assert f.calls == [("ch", 3), ("acq", [(7, True)], 2.6e6)]


_BLAS_PROBE = """
import receiver
receiver.limit_blas_threads()         # first: the BLAS thread count before numpy loads
import numpy as np
from receiver.acquisition import refine_doppler
rng = np.random.default_rng(2)
x = (rng.standard_normal(520_000) + 1j * rng.standard_normal(520_000)).astype(np.complex64)
print(repr(refine_doppler(x, 2.6e6, 0.0, 7, 100.5, 1250.0, 125.0, block_ms=10, n_blocks=20)))
"""


@pytest.mark.skipif((__import__("os").cpu_count() or 1) < 2, reason="needs 2 cores for a threaded BLAS")
def test_results_do_not_depend_on_the_environments_blas_threads():
    """The fine Doppler's line powers are BLAS matrix products; a threaded BLAS sums them in a
    thread-count-dependent order (the last bit of the Doppler moved with OPENBLAS_NUM_THREADS, and through
    a vector loop whole figure results between -j 1 and -j 2).  receiver.limit_blas_threads() (what the
    command line does first) pins BLAS to one thread unless the environment says otherwise: a process with
    nothing set equals one told 1 thread."""
    import os
    import subprocess
    env = {k: v for k, v in os.environ.items() if k not in ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS",
                                                             "OMP_NUM_THREADS")}
    out = [subprocess.run([sys.executable, "-c", _BLAS_PROBE], capture_output=True, text=True, check=True,
                          cwd=ROOT, env={**env, **extra}).stdout for extra in ({}, {"OPENBLAS_NUM_THREADS": "1"})]
    assert out[0] == out[1] and out[0].strip()


def test_importing_the_package_changes_no_environment_variable():
    """No import-time side effect: importing receiver and its stages leaves the environment as it was (the BLAS
    default is the entry points' explicit call)."""
    import os
    import subprocess
    env = {k: v for k, v in os.environ.items() if k not in ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS",
                                                             "OMP_NUM_THREADS")}
    probe = ("import os, json; before = dict(os.environ); import receiver, receiver.pipeline; "
             "print(json.dumps(sorted(k for k in os.environ if os.environ.get(k) != before.get(k))))")
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True, cwd=ROOT,
                         env=env).stdout
    assert out.strip() == "[]"
