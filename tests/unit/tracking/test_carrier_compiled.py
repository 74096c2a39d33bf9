"""The carrier loops' compiled twins (receiver/tracking/loops/compiled.py) against the Python-stepped
loops: bit for bit the same channel-epoch records for every variant, on 2.5 s of the reference
recording (hand-over from the built-in pull-in loop at bit sync included)."""
import numpy as np
import pytest

from repo_paths import TOKYO_REC
from receiver.schema import load_receiver_config
from receiver.tracking import kernel as K
from receiver.tracking.carrier import REGISTRY
from receiver.tracking.loops import compiled as LC
from receiver.tracking.scalar import Channel

FS = 2.6e6
SATS = [(23, -1867.2, 476.88), (13, -3515.0, 349.39)]      # strongest and weakest of the recording (44, 34 dB-Hz)
VARIANTS = [v for v in REGISTRY if v != "pll"]


@pytest.fixture(scope="module")
def samples():
    if not TOKYO_REC.exists():
        pytest.skip("../shared/data reference recording absent")
    raw = np.memmap(TOKYO_REC, np.int8, "r")[:int(2 * 2.5 * FS)]
    return (raw[0::2] + 1j * raw[1::2]).astype(np.complex64)


def _track(x, variant, compiled, prn, dop, cp):
    cfg = load_receiver_config(None, [("tracking.carrier.variant", variant)])
    ch = Channel(prn, dop, cp, 0, cfg.tracking, FS, 0.0)
    ch.use_compiled_loop = compiled
    chunk, pad, recs = int(0.5 * FS), int(0.03 * FS), []
    for start in range(0, len(x) - chunk, chunk):
        s = ch.next_sample if start else 0
        recs.append(ch.process(x[s:start + chunk + pad], s))
    return ch, np.concatenate(recs)


def test_every_variant_has_a_compiled_twin():
    assert set(VARIANTS) == set(LC.KINDS)


@pytest.mark.slow
@pytest.mark.parametrize("variant", VARIANTS)
def test_compiled_loop_equals_the_python_stepped_loop(samples, variant):
    for prn, dop, cp in SATS:
        ch_c, a = _track(samples, variant, True, prn, dop, cp)
        ch_p, b = _track(samples, variant, False, prn, dop, cp)
        assert ch_c._loop_started and ch_p._loop_started          # the variant's loop ran (after bit sync)
        assert ch_c.cfg[K.C_CARRIER_EXTERNAL] == 1.0 and not ch_c.lost          # the loop owns the NCO
        assert len(a) == len(b) > 2000
        assert (a["state"] == b["state"]).all() and (a["sample_index"] == b["sample_index"]).all()
        for name in ("doppler_hz", "carrier_phase_cycles", "code_phase_chips", "code_rate_hz", "prompt_i",
                     "prompt_q", "cn0_dbhz", "pli"):
            np.testing.assert_array_equal(a[name], b[name], err_msg=name)


def test_stale_numba_cache_of_a_caller_is_dropped(tmp_path, monkeypatch):
    """numba keys a cached function on its own file only: a cache older than a module it calls is removed
    (receiver/tracking/_jitcache.py), a fresher one is kept."""
    import os

    from receiver.tracking import _jitcache as J
    (tmp_path / "__pycache__").mkdir()
    for name in ("callee.py", "caller.py"):
        (tmp_path / name).write_text("# source\n")
    idx = tmp_path / "__pycache__" / "caller.f-10.py311.nbi"
    data = tmp_path / "__pycache__" / "caller.f-10.py311.1.nbc"
    other = tmp_path / "__pycache__" / "callee.g-3.py311.nbi"
    for f in (idx, data, other):
        f.write_bytes(b"x")
    monkeypatch.setattr(J, "_HERE", str(tmp_path))
    monkeypatch.setattr(J, "DEPENDS", {"caller.py": ["callee.py"]})
    t = os.stat(tmp_path / "callee.py").st_mtime_ns
    os.utime(idx, ns=(t + 10 ** 9, t + 10 ** 9))           # cache newer than the callee: kept
    assert J.refresh() == [] and idx.exists()
    os.utime(idx, ns=(t - 10 ** 9, t - 10 ** 9))           # the callee changed after: dropped
    assert sorted(J.refresh()) == sorted([str(idx), str(data)])
    assert not idx.exists() and not data.exists() and other.exists()
