"""Helpers for the simulator tests: read IF files and build replicas from truth with plain numpy.

Nothing here uses the simulator's kernel: replicas are made from the truth file's code phase and carrier
phase only, so the tests check the kernel against the truth independently.
"""
import numpy as np

from receiver.source.io import FORMATS, SampleReader
from receiver.gnss.signals import ca_code


def read_if(path, fmt, **kw):
    f = FORMATS[fmt]
    if f.kind in ("int", "float"):
        raw = np.fromfile(path, dtype=f.dtype).astype(np.float64)
        return raw[0::2] + 1j * raw[1::2] if f.ncomp == 2 else raw + 0j
    r = SampleReader(path, fmt, 1.0, **kw)                    # packed / offset formats: the reader
    return r.read(0, r.n_samples).astype(np.complex128)


def code_chips_total(g):
    """Truth code phase unwrapped to a continuous chip count (relative to the nominal chip rate)."""
    ts = g["time_s"][:]
    nominal = 1.023e6 * ts
    return ts, np.unwrap(np.mod(g["code_phase_chips"][:] - nominal, 1023.0), period=1023.0) + nominal


def replica(g, fs, n, if_hz=0.0, prn=None, code_offset=0.0, doppler_offset=0.0):
    """Code x carrier replica (no data) for samples 0..n-1 from the truth of one satellite group."""
    prn = int(g.attrs["prn"]) if prn is None else prn
    t = np.arange(n) / fs
    ts, chips = code_chips_total(g)
    cp = np.interp(t, ts, chips) + code_offset
    ph = np.interp(t, ts, g["carrier_phase_cycles"][:]) + if_hz * t + doppler_offset * t
    code = ca_code(prn).astype(np.float64)
    return code[np.floor(cp).astype(np.int64) % 1023] * np.exp(2j * np.pi * ph), cp


def period_correlations(x, rep, cp):
    """Correlations over whole code periods (windows between chip counts 1023 m and 1023 (m+1)),
    so that no data-bit edge falls inside a window.  Returns (P, n_samples_per_window)."""
    m0 = int(np.ceil(cp[0] / 1023.0))
    m1 = int(np.floor(cp[-1] / 1023.0))
    edges = np.searchsorted(cp, 1023.0 * np.arange(m0, m1 + 1))
    prod = x * np.conj(rep)
    csum = np.concatenate(([0.0], np.cumsum(prod)))
    p = csum[edges[1:]] - csum[edges[:-1]]
    return p, np.diff(edges)


def test_period_correlations_exact_for_a_known_signal():
    # a synthetic signal built the same way as the helpers' replica: the correlation is exact
    class G(dict):
        attrs = {"prn": 3}
    fs = 2.0e6
    ts = np.arange(0, 0.05, 0.01)
    g = G(time_s=ts, code_phase_chips=np.mod(17.25 + 1.023e6 * ts * (1 + 1e-6), 1023.0),
          carrier_phase_cycles=-1575.42 * ts)
    n = int(0.04 * fs)
    rep, cp = replica(g, fs, n)
    p, w = period_correlations(0.5 * rep, rep, cp)
    assert np.allclose(p, 0.5 * w)
    assert np.all(np.abs(w - fs * 1e-3) <= 1)
