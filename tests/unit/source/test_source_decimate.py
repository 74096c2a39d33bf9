"""The decimating / resampling input stage (receiver/source/decimate.py): exact time tags, block-wise
reads equal to one pass, the factor `auto` picks, and a 16.368 MS/s real-IF 2-bit recording received
through it (C/N0 and Doppler against the simulated values and against full-rate processing)."""
from types import SimpleNamespace

import numpy as np
import pytest

from receiver.errors import UserError
from receiver.source.decimate import DecimatingReader, phase_grid, plan

from repo_paths import ROOT
FS = 16.368e6
IF = 4.1304e6


class ArrayReader:
    """A SampleReader over an array (real samples as complex64 with zero imaginary part)."""

    def __init__(self, x, fs, real=True):
        self.x, self.fs, self.first, self.end = x, fs, 0, len(x)
        self.format = SimpleNamespace(complex=not real)

    def read(self, start, n):
        start = max(start, self.first)
        return self.x[start:min(start + n, self.end)].copy()


def _tones(n, tones, real=True):
    """Real samples a cos(...) or complex ones (a / 2) exp(j ...): the same component at IF + f."""
    t = np.arange(n) / FS
    x = np.zeros(n, complex)
    for f, a, ph in tones:
        arg = 2 * np.pi * (IF + f) * t + ph
        x += a * np.cos(arg) if real else 0.5 * a * np.exp(1j * arg)
    return x.astype(np.complex64)


def test_plan_auto_and_explicit():
    assert plan("auto", 16.368e6, 1.023e6) == (250, 1023)          # -> 4 MS/s exactly
    assert plan("auto", 20e6, 1.023e6) == (1, 5)
    assert plan("auto", 2.6e6, 1.023e6) == (1, 1)                  # low rates: no stage
    assert plan("auto", 5.2e6, 1.023e6) == (1, 1)
    assert plan("auto", 38.192e6, 2.046e6)[0] * 38.192e6 / plan("auto", 38.192e6, 2.046e6)[1] == \
        pytest.approx(8e6)                                         # BeiDou B1I: >= 3.9 chip rates
    assert plan(4, 16.368e6, 1.023e6) == (1, 4) and plan(1, 16.368e6, 1.023e6) == (1, 1)
    with pytest.raises(UserError, match="cannot hold"):
        plan(8, 16.368e6, 1.023e6)
    with pytest.raises(UserError, match="whole number of samples per millisecond"):
        plan(5, 16.368e6, 1.023e6)                                 # 3.2736 MS/s
    with pytest.raises(UserError, match="must be auto or an integer"):
        plan(True, 16.368e6, 1.023e6)
    # the code-phase grid: 16.368/4 = 4.092 MS/s has only 4 alignments per chip, 4 MS/s 4000
    assert phase_grid(16.368e6 / 4, 1.023e6) == 4 and phase_grid(4e6, 1.023e6) == 4000


@pytest.mark.slow
@pytest.mark.parametrize("lm,real", [((250, 1023), True), ((1, 4), True), ((250, 1023), False)])
def test_tones_arrive_with_exact_time_tags(lm, real):
    """Tones at IF + f (real samples, or complex ones) come out at f with the phase they have at
    t = k / fs_out: a time tag off by one input sample would turn the 0.9 MHz tone's phase by 0.35 rad."""
    n = 400_000
    tones = [(0.9e6, 1.0, 0.3), (-0.7e6, 0.5, -1.1), (3.0e3, 0.25, 2.0), (5.0e6, 1.0, 0.0)]   # last: out of band
    d = DecimatingReader(ArrayReader(_tones(n, tones, real), FS, real), *lm, IF, 1.023e6)
    y = d.read(d.first, d.n_samples)
    k = np.arange(len(y))[200:-200]
    t = k / d.fs
    for f, a, ph in tones[:3]:
        z = np.mean(y[k] * np.exp(-2j * np.pi * f * t))
        assert abs(z) == pytest.approx(a / 2, rel=0.03)            # pass-band ripple within 0.26 dB
        assert np.angle(z * np.exp(-1j * ph)) == pytest.approx(0.0, abs=0.01)
    resid = y[k] - sum(a / 2 * np.exp(1j * (2 * np.pi * f * t + ph)) for f, a, ph in tones[:3])
    assert np.sqrt(np.mean(np.abs(resid) ** 2)) < 0.03 * 0.5       # pass-band ripple + the 5 MHz tone's alias


def test_blockwise_reads_equal_one_pass():
    rng = np.random.default_rng(3)
    x = (rng.integers(-2, 2, 300_000) * 2 + 1).astype(np.complex64)
    d = DecimatingReader(ArrayReader(x, FS), 250, 1023, IF, 1.023e6)
    whole = d.read(d.first, d.n_samples)
    parts = np.concatenate([d.read(k, 997) for k in range(d.first, d.end, 997)])
    assert np.array_equal(whole, parts)
    assert np.array_equal(d.read(12_345, 50), whole[12_345:12_395])
    assert d.n_samples == -(-300_000 * 250 // 1023)


@pytest.fixture(scope="module")
def highrate(tmp_path_factory):
    from receiver.sim.simulate import simulate
    d = tmp_path_factory.mktemp("highrate")
    paths = simulate(ROOT / "configs" / "scenarios" / "static_default.yaml", d / "hr.bin",
                     [("time.duration_s", 1.0), ("constellation.prns", [1, 6, 9]), ("cn0.dbhz", 45.0),
                      ("clock.noise", "none"), ("frontend.format", "packed2_real"),
                      ("frontend.sample_rate_hz", FS), ("frontend.if_hz", IF)], progress=False)
    return d, paths


def _run(d, paths, name, decimate):
    import h5py
    from receiver.schema import load_receiver_config
    from receiver.pipeline import run
    out = d / f"{name}.h5"
    cfg = load_receiver_config(paths["yaml"], [("output.path", str(out)), ("navigation.enabled", False),
                                               ("acquisition.prns", [1, 6, 9, 12]),
                                               ("input.decimate", decimate)])
    run(cfg, quiet=True, log=lambda *a: None)
    res = {}
    with h5py.File(out) as h:
        assert h.attrs["sample_rate_hz"] == (4e6 if decimate == "auto" else FS)
        for name_, g in h["channels"].items():
            t = g["time_s"][:]
            m = (t > 0.6) & (g["pll_lock"][:] > 0)
            res[int(name_[1:])] = (float(np.median(g["cn0_dbhz"][:][m])), float(np.median(g["doppler_hz"][:][m])),
                                   t, g["sample_index"][:])
    return res


@pytest.mark.slow
def test_highrate_file_through_the_stage(highrate):
    """16.368 MS/s 2-bit real IF -> 4 MS/s complex: the simulated satellites and no other, their C/N0
    (45 dB-Hz minus the 2-bit loss ~0.55 dB and the stage's ~0.5 dB, README), the simulated Doppler, and
    time_s = sample_index / 4 MS/s.  (Processing the same file at full rate -- `input.decimate: 1` --
    gives 0.5 dB more C/N0; not repeated here: acquisition at 16 MS/s alone takes a minute.)"""
    import h5py
    d, paths = highrate
    dec = _run(d, paths, "dec", "auto")
    assert set(dec) == {1, 6, 9}
    with h5py.File(paths["truth"]) as t:
        sats = {int(k[1:]): (t["satellites"][k]["time_s"][:], t["satellites"][k]["doppler_hz"][:])
                for k in t["satellites"]}
    for prn, (cn0, dop, t, si) in dec.items():
        assert 43.3 < cn0 < 45.0, (prn, cn0)
        tt, dd = sats[prn]
        assert abs(dop - np.median(dd[tt > 0.6])) < 3.0, (prn, dop)
        assert np.allclose(t, si / 4e6, atol=1e-12)


@pytest.mark.parametrize("fmt", ["int8_real", "packed2_real"])
def test_real_spectral_inversion_is_consistent_across_reads(tmp_path, fmt):
    """iq_swap on a real file multiplies sample n by (-1)^n with n the FILE index, so a read starting at an
    odd index gives the same samples as a longer read (the resampling stage reads at any position)."""
    from receiver.source.io import SampleReader, quantize
    rng = np.random.default_rng(5)
    p = tmp_path / "r.bin"
    quantize(rng.normal(0, 3, 4096).astype(np.complex64), fmt).tofile(p)
    r = SampleReader(p, fmt, 1e6, iq_swap=True)
    whole = r.read(0, 4096)
    for start in (1, 3, 1000, 1001):
        assert np.array_equal(r.read(start, 500), whole[start:start + 500]), start


@pytest.mark.parametrize("fmt,swap", [("packed2_real", False), ("packed2_real", True), ("packed1_real", False),
                                      ("packed4_real", True)])
def test_fused_packed_path_equals_the_generic_one(tmp_path, fmt, swap):
    """A packed real file is unpacked inside the compiled call (and iq_swap becomes a mixer offset of
    fs_in / 2): the samples equal those of the generic path (the reader's complex64 samples through the
    same complex taps) to float32 rounding, at the span's edges too (skip_s, duration_s), and every thread
    count gives the same samples bit for bit."""
    from receiver import threads as T
    from receiver.source.io import SampleReader, quantize
    rng = np.random.default_rng(11)
    p = tmp_path / "r.bin"
    quantize((rng.normal(0, 2, 160_000) + _tones(160_000, [(0.3e6, 4.0, 0.5)]).real).astype(np.complex64),
             fmt).tofile(p)
    r = SampleReader(p, fmt, FS, skip_s=1001 / FS, duration_s=140_000 / FS, iq_swap=swap)
    fused = DecimatingReader(r, 250, 1023, IF, 1.023e6)
    assert fused._packed
    full = SampleReader(p, fmt, FS, iq_swap=swap)
    arr = ArrayReader(full.read(0, full.n_file), FS)
    arr.first, arr.end = r.first, r.end
    generic = DecimatingReader(arr, 250, 1023, IF, 1.023e6)
    assert not generic._packed and (generic.first, generic.end) == (fused.first, fused.end)
    a = fused.read(fused.first, fused.n_samples)
    b = generic.read(generic.first, generic.n_samples)
    scale = np.sqrt(np.mean(np.abs(b) ** 2))
    assert a.shape == b.shape and np.max(np.abs(a - b)) < 1e-4 * scale
    try:
        outs = []
        for n in (1, 2, 3):
            T.set_threads(n)
            outs.append(np.concatenate([fused.read(k, 20_011) for k in range(fused.first, fused.end, 20_000)]))
        assert all(np.array_equal(outs[0], o) for o in outs[1:])
    finally:
        T.set_threads(None)


@pytest.mark.slow
@pytest.mark.parametrize("fmt", ["packed2_real", "packed4_real", "packed1_real"])
def test_unpack_kernel_gives_the_table_values_at_any_field_and_offset(fmt):
    """The compiled unpacking of whole bytes (a four-copy path for 2-bit fields) writes exactly the byte
    table's values of fields first_field .. first_field + n - 1, and nothing outside x[off:off + n]."""
    from receiver.source.decimate import _unpack_real
    from receiver.source.io import FORMATS, byte_table
    f = FORMATS[fmt] if isinstance(FORMATS, dict) else next(x for x in FORMATS if x.name == fmt)
    table = byte_table(f)
    k = table.shape[1]
    raw = np.random.default_rng(5).integers(0, 256, 700).astype(np.uint8)
    fields = table[raw].ravel()
    for first in range(k):
        for n in (0, 1, k - 1, k, k + 1, 3 * k + 2, (raw.size - 1) * k - first):
            x = np.full(n + 9, -7.0, np.float32)
            _unpack_real(raw, table, first, x, 4, n)
            assert np.array_equal(x[4:4 + n], fields[first:first + n]), (first, n)
            assert np.all(x[:4] == -7.0) and np.all(x[4 + n:] == -7.0)


def _rate_out(fs, lm):
    return fs * lm[0] / lm[1]


@pytest.mark.parametrize("fs", [16.3676e6, 16.3671e6, 2.0461e6, 3.0005e6])
def test_plan_auto_rates_that_are_not_whole_samples_per_ms(fs):
    """A front end's rate that is not a whole number of samples per millisecond (the SiGe GN3S's 16.3676
    MS/s: 16367.6 per ms) is resampled to one, which acquisition needs: high rates to the lowest whole rate
    from 4 MS/s up, low rates slightly up; the ratio's integers stay <= MAX_L; the code-phase grid stays
    fine (not a rate commensurate with the chip rate)."""
    from receiver.source.decimate import MAX_L
    lm = plan("auto", fs, 1.023e6)
    out = _rate_out(fs, lm)
    assert max(lm) <= MAX_L and lm != (1, 1)
    assert abs(out * 1e-3 - round(out * 1e-3)) < 1e-6
    if fs > 6e6:
        assert 4e6 <= out <= 4.1e6
    else:
        assert fs < out <= 1.01 * fs
    assert phase_grid(out, 1.023e6) > 100
    with pytest.raises(UserError, match="whole number of samples per millisecond"):
        plan(1, fs, 1.023e6)                                       # the stage switched off: a clear error


def test_plan_auto_whole_rates_unchanged_and_unreachable_rate():
    assert plan("auto", 2.048e6, 1.023e6) == (1, 1) and plan("auto", 4.092e6, 1.023e6) == (1, 1)
    with pytest.raises(UserError, match="resample the recording"):
        plan("auto", 2046100.3, 1.023e6)                           # 20461003 / 10: no small ratio


def test_acquisition_at_a_rate_that_is_not_whole_samples_per_ms():
    """2.0461 MS/s complex samples (2046.1 per ms) through the stage `auto` plans: the satellite is found
    at its Doppler and code phase (before the stage, acquisition cannot fold code periods)."""
    from receiver.acquisition import search
    from synth import make_signal
    fs = 2.0461e6
    x = make_signal([dict(prn=9, doppler_hz=-1730.0, code_phase_chips=400.25, cn0_dbhz=44.0)], fs, 0.25,
                    seed=3).astype(np.complex64)
    d = DecimatingReader(ArrayReader(x, fs, real=False), *plan("auto", fs, 1.023e6), 0.0, 1.023e6)
    y = d.read(d.first, int(0.2 * d.fs))
    r = search(y, d.first, d.fs, 0.0, [9, 10])
    assert r[0].detected and not r[1].detected
    assert abs(r[0].doppler_hz + 1730.0) < 20.0
    # the code phase at the stream's first sample (time 0) is the simulated one
    assert abs((r[0].code_phase_chips - 400.25 + 511.5) % 1023 - 511.5) < 0.5
