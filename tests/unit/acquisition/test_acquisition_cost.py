"""Cheaper acquisition (issue 19): the fine Doppler by a direct DFT at the lines it needs equals the
zero-padded-FFT estimate it replaced; the cold search after a fix covers every satellite's Doppler with a
window narrower than the configured grid."""
import numpy as np
import pytest

from receiver.acquisition import refine_doppler
from receiver.gnss.signals import GPS_L1CA, sample_code

from synth import make_signal

FS = 2.6e6


def _refine_fft(samples, fs, prn, code_phase_chips, coarse_hz, bin_hz, block_ms=10, n_blocks=20):
    """The former implementation: n_blocks zero-padded FFTs of nfft points, power summed, peak within
    +/- 1.5 bins interpolated (written out here as the reference)."""
    n = int(round(block_ms * 1e-3 * fs))
    code = sample_code(GPS_L1CA.code(prn), GPS_L1CA.chip_rate * (1.0 + coarse_hz / GPS_L1CA.carrier_hz), fs,
                       n * n_blocks, code_phase_chips)
    t = np.arange(n * n_blocks) / fs
    x = samples[:n * n_blocks] * code * np.exp(-2j * np.pi * coarse_hz * t)
    nfft = 1 << int(np.ceil(np.log2(n * 8)))
    spec = sum(np.abs(np.fft.fft(x[k * n:(k + 1) * n], nfft)) ** 2 for k in range(n_blocks))
    freqs = np.fft.fftfreq(nfft, 1.0 / fs)
    idx = np.flatnonzero(np.abs(freqs) <= 1.5 * bin_hz)
    i = idx[np.argmax(spec[idx])]
    a, b, c = spec[i - 1], spec[i], spec[(i + 1) % nfft]
    d = 0.5 * (a - c) / (a - 2 * b + c) if 0 < i < nfft - 1 else 0.0
    return coarse_hz + freqs[i] + d * fs / nfft


@pytest.mark.slow
@pytest.mark.parametrize("true_hz, coarse_hz", [(1234.5, 1250.0), (-3377.0, -3375.0), (61.0, 0.0),
                                                (-150.0, 0.0)])
def test_fine_doppler_equals_the_fft_estimate(true_hz, coarse_hz):
    x = make_signal([dict(prn=7, doppler_hz=true_hz, code_phase_chips=100.5, cn0_dbhz=40.0)], FS, 0.2,
                    seed=3).astype(np.complex64)
    got = refine_doppler(x, FS, 0.0, 7, 100.5, coarse_hz, 125.0, block_ms=10, n_blocks=20)
    ref = _refine_fft(x, FS, 7, 100.5, coarse_hz, 125.0)
    assert got == pytest.approx(ref, abs=1e-6)
    assert abs(got - true_hz) < 5.0


@pytest.mark.slow
def test_cold_search_window_after_a_fix_covers_the_tracked_satellites(tokyo_run):
    """At every fix of the reference run, the Doppler of every tracked satellite lies inside the cold-search
    window computed from that fix (clock drift, velocity), and the window is narrower than the grid."""
    import h5py
    from types import SimpleNamespace

    from receiver.schema import load_receiver_config
    from receiver.tracking.channels import ChannelManager
    cfg = load_receiver_config(None, [])
    with h5py.File(tokyo_run) as f:
        nav = f["navigation"]
        fixes = {k: nav[k][:] for k in ("time_s", "clock_drift_mps", "velocity_ecef")}
        chans = {k: (f["channels"][k]["time_s"][:], f["channels"][k]["doppler_hz"][:]) for k in f["channels"]}
    fake_nav = SimpleNamespace(last_fix=None)
    m = ChannelManager(cfg, None, fake_nav, FS, 0.0, GPS_L1CA, acquire=None)
    assert m._cold_doppler_window() is None                     # no fix, no channel: the configured grid
    checked = 0
    for t, drift, v in zip(fixes["time_s"][::20], fixes["clock_drift_mps"][::20], fixes["velocity_ecef"][::20]):
        fake_nav.last_fix = (0, SimpleNamespace(clock_drift_mps=drift, velocity_ecef=v))
        centre, half = m._cold_doppler_window()
        assert half < cfg.acquisition.doppler_max_hz * 0.65
        for ts, dop in chans.values():
            i = np.searchsorted(ts, t)
            if 0 < i < len(ts):
                assert abs(dop[i] - centre) < half - 300.0, (t, dop[i], centre, half)
                checked += 1
    assert checked > 50


@pytest.mark.slow
def test_cold_search_window_before_a_fix_covers_every_satellite(tokyo_run):
    """Before a fix the window comes from the Dopplers of the channels in lock: on the reference run, each
    satellite's Doppler lies inside the window computed from the other nine (leave one out), and the
    window is narrower than the configured grid."""
    import h5py
    from types import SimpleNamespace

    from receiver.schema import load_receiver_config
    from receiver.tracking import kernel as K
    from receiver.tracking.channels import ChannelManager
    cfg = load_receiver_config(None, [])
    with h5py.File(tokyo_run) as f:
        chans = {k: (f["channels"][k]["time_s"][:], f["channels"][k]["doppler_hz"][:]) for k in f["channels"]}
    m = ChannelManager(cfg, None, SimpleNamespace(last_fix=None), FS, 0.0, GPS_L1CA, acquire=None)

    def fake(dop, lock=1.0):
        st = np.zeros(K.N_STATE)
        st[K.S_LOCK] = lock
        return SimpleNamespace(st=st, cn0_dbhz=40.0, doppler_hz=dop, lost=False)

    m.channels = {0: fake(1234.0, lock=0.0)}                     # not in lock: not used
    assert m._cold_doppler_window() is None
    checked = 0
    for t in np.arange(2.0, 40.0, 4.0):
        dops = {}
        for k, (ts, dop) in chans.items():
            i = np.searchsorted(ts, t)
            if 0 < i < len(ts):
                dops[k] = dop[i]
        assert len(dops) >= 8
        for j in dops:
            m.channels = {k: fake(d) for k, d in dops.items() if k != j}
            centre, half = m._cold_doppler_window()
            assert half < cfg.acquisition.doppler_max_hz
            assert abs(dops[j] - centre) < half - 300.0, (t, j, dops[j], centre, half)
            checked += 1
    assert checked > 80


@pytest.mark.parametrize("fs, block_ms, n_blocks, bin_hz", [(2.6e6, 10, 20, 125.0), (4e6, 10, 20, 125.0),
                                                            (16.368e6, 7, 3, 125.0), (2.6e6, 10, 4, 500.0),
                                                            (2.6e6, 1, 40, 125.0)])
def test_segmented_line_powers_equal_the_direct_dft(fs, block_ms, n_blocks, bin_hz):
    """The fine Doppler's line powers by segment moments (Taylor series within a segment) equal the direct
    DFT at the lines to rounding."""
    from receiver.acquisition.code_search import _line_powers, _line_powers_direct
    rng = np.random.default_rng(11)
    n = int(round(block_ms * 1e-3 * fs))
    nfft = 1 << int(np.ceil(np.log2(n * 8)))
    kmax = int(np.floor(1.5 * bin_hz * nfft / fs))
    ks = np.arange(-kmax - 1, kmax + 2)
    t = np.arange(n * n_blocks) / fs
    y = (0.3 * np.exp(2j * np.pi * 1077.3 * t) + rng.standard_normal(t.size)
         + 1j * rng.standard_normal(t.size)).astype(np.complex64).reshape(n_blocks, n)
    ref = _line_powers_direct(y, 1000.0 / fs, ks, nfft)
    got = _line_powers(y, 1000.0 / fs, ks, nfft)
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-13 * ref.max())


@pytest.mark.slow
def test_high_sensitivity_block_powers_equal_the_numpy_formulation():
    """acquisition.high_sensitivity._BlockSpectra.powers (compiled gather / shifted power sum) gives bit for bit the
    block sums of the numpy formulation it replaced (fancy-index gather, square, take_along_axis, add)."""
    import scipy.fft as sfft

    from receiver.acquisition.high_sensitivity import _BlockSpectra, _code_fft
    fs, m, k = FS, 10, 20
    x = make_signal([dict(prn=5, doppler_hz=4345.0, code_phase_chips=300.0, cn0_dbhz=38.0)], fs, 0.2,
                    seed=4).astype(np.complex64)
    dopplers = 4000.0 + np.arange(-1000.0, 1000.0 + 25.0, 50.0)
    sp = _BlockSpectra(x, fs, 0.0, dopplers, m, k)
    cf = _code_fft(GPS_L1CA, 5, fs, sp.n1)
    sel = np.arange(len(dopplers))
    got = sp.powers(cf, fs, GPS_L1CA.carrier_hz, [sel])[0]
    ref = np.zeros_like(got)
    n1, cols = sp.n1, np.arange(sp.n1)
    drift = np.outer(np.arange(k) * m * 1e-3 * fs, dopplers / GPS_L1CA.carrier_hz)
    for r in np.unique(sp.frac):
        rows = np.flatnonzero(sp.frac == r)
        ix = sp.idx[rows]
        for kk in range(k):
            corr = sfft.ifft(sp.spectra[r][kk][ix] * cf[None, :], axis=1)
            p = corr.real ** 2 + corr.imag ** 2
            sh = np.rint(drift[kk, rows]).astype(np.int64)
            ref[kk & 1, rows] += np.take_along_axis(p, (cols[None, :] - sh[:, None]) % n1, axis=1)
    np.testing.assert_array_equal(got, ref)
    assert np.rint(np.abs(drift)).max() >= 1             # the shifts were exercised


@pytest.mark.parametrize("m,k,centre_hz,step_hz", [(4, 10, 0.0, None), (1, 6, -790.0, 300.0), (2, 3, 1234.5, None)])
def test_search_power_equals_the_gathered_formulation(m, k, centre_hz, step_hz):
    """The fast search's power grid (code spectrum shifted per Doppler row, block spectra used as they
    are) equals the formulation where each Doppler row gathers its lines of the block spectrum, to float32
    rounding, with the same peak cell in every row; and the signal is found where it was put."""
    from receiver.acquisition.code_search import _code_fft, _Spectra
    fs = FS
    x = make_signal([dict(prn=12, doppler_hz=centre_hz + 1510.0, code_phase_chips=512.3, cn0_dbhz=45.0)], fs,
                    m * k * 1e-3 + 0.001, seed=2).astype(np.complex64)
    step = step_hz or 1.0 / (2 * m * 1e-3)
    dopplers = centre_hz + np.arange(-5000.0, 5000.0 + step / 2, step)
    sp = _Spectra(x, fs, 0.0, dopplers, m, k)
    cf = _code_fft(GPS_L1CA, 12, fs, sp.n1)
    got = sp.power(cf)
    ref = np.zeros_like(got)
    for r in sp.fracs:
        rows = np.flatnonzero(sp.frac == r)
        for kk in range(k):
            corr = np.fft.ifft(sp.spectra[r][kk][sp.idx[rows]] * cf[None, :], axis=1)
            ref[rows] += (corr.real ** 2 + corr.imag ** 2).astype(np.float32)
    np.testing.assert_allclose(got, ref, rtol=0, atol=2e-6 * ref.max())
    assert np.array_equal(np.argmax(got, axis=1), np.argmax(ref, axis=1))
    d, s = np.unravel_index(np.argmax(got), got.shape)
    assert abs(dopplers[d] - (centre_hz + 1510.0)) <= step
    chips = (-s * GPS_L1CA.chip_rate / fs) % 1023
    assert abs((chips - 512.3 + 511.5) % 1023 - 511.5) < 0.5


@pytest.mark.parametrize("m,k", [(4, 10), (1, 5), (2, 7)])
def test_verification_power_equals_the_search_power(m, k):
    """The verification dwell's power (each block's carrier wiped off at the bin, folded onto one code
    period, one FFT of a period) equals the search's (every m-th line of the block spectrum) at off-grid
    Dopplers, to float32 rounding."""
    from receiver.acquisition.code_search import _code_fft, _folded_power, _Spectra
    x = make_signal([dict(prn=7, doppler_hz=-2233.3, code_phase_chips=100.7, cn0_dbhz=42.0)], FS,
                    m * k * 1e-3 + 0.001, seed=5).astype(np.complex64)
    dopplers = -2233.3 + np.array([-1.0, 0.0, 1.0]) / (2 * m * 1e-3) + 37.0
    cf = _code_fft(GPS_L1CA, 7, FS, 2600)
    ref = _Spectra(x, FS, 0.0, dopplers, m, k).power(cf)
    got = _folded_power(x, FS, 0.0, dopplers, m, k, cf)
    np.testing.assert_allclose(got, ref, rtol=0, atol=2e-6 * ref.max())
    assert int(np.argmax(got[1])) == int(np.argmax(ref[1]))


@pytest.mark.parametrize("phase,ratio", [(930.93, 1.023e6 * (1 + 726 / 1575.42e6) / 2.6e6), (1022.9999, 0.9999),
                                         (0.0, 0.25), (-3.7, 0.3934)])
def test_code_wipe_equals_the_sampled_code(phase, ratio):
    """The fine Doppler's compiled code wipe-off (running code-length offset instead of a modulo per
    sample) multiplies every sample by the chip numpy's sample_code picks, across code-period ends."""
    from receiver.acquisition.code_search import _code_wipe
    rng = np.random.default_rng(1)
    x = (rng.normal(size=30000) + 1j * rng.normal(size=30000)).astype(np.complex64)
    code = GPS_L1CA.code(5)
    ref = x * sample_code(code, ratio * FS, FS, len(x), phase)
    np.testing.assert_array_equal(_code_wipe(x, code, phase, ratio), ref)
