"""Galileo E1 channels in the vector loop: the BOC(1,1) code discriminator (receiver.tracking.vector.discriminators)
against a numerical correlation of the E1-C replica, and the vector loop's compiled Galileo epoch
(receiver.tracking.vector.galileo.gal_epoch) on a synthetic E1 signal made here from the ICD codes (E1-B symbols,
E1-C x CS25 transmitted as -e_C, 45 dB-Hz in seeded noise): the frequency discriminator of its pilot halves reads
the carrier offset, prompt1 carries the E1-B symbols referred to the pilot's phase, the C/N0 is the simulated one,
the code discriminator the code offset; a channel handed back to its scalar loops (the vector tracker's fall-back)
pulls in and locks again, its code-period count continuous."""
import types

import numpy as np
import pytest

from receiver.gnss.gal_codes import E1_CHIP_RATE, E1_CODE_LEN, boc11, cs25_signs, e1b_code, e1c_code
from receiver.gnss.signals import C_LIGHT
from receiver.runfile.record import STATE_BIT_SYNC
from receiver.tracking import kernel as K
from receiver.tracking.gal import _correlate_block
from receiver.tracking.gal_channels import GalTrack
from receiver.tracking.vector.discriminators import (code_disc_boc_m, code_discriminator,
                                                     code_discriminator_boc, freq_disc_hz)
from receiver.tracking.vector.galileo import gal_epoch

PRN = 11
M_PER_CHIP = C_LIGHT / E1_CHIP_RATE


def _epoch_el(fs, tau, d, cp=100.25):
    """|E|, |L| of one 4-ms E1-C period whose code phase leads the replica's (at cp chips) by tau chips (no noise,
    no carrier), correlated by the Galileo correlator with E-L spacing d."""
    rep = boc11(e1c_code(PRN)).astype(np.float32)
    step = E1_CHIP_RATE / fs
    n = int(4e-3 * fs)
    chips = cp + tau + np.arange(n) * step
    x = rep[np.floor(2.0 * chips).astype(np.int64) % rep.size].astype(np.complex64)
    e, p, l, _ = _correlate_block(x, 0, n, cp, step, 0.0, 0.0, rep, rep, 0.5 * d)
    return abs(e), abs(l), abs(p)


@pytest.mark.parametrize("fs", [4.0e6, 16.368e6 + 1234.0])
@pytest.mark.parametrize("d", [0.2, 0.1])
def test_boc_code_discriminator_slope_and_sign(fs, d):
    """Measured minus replica pseudorange from a numerical correlation: a signal leading the replica by tau chips
    (a later transmit time, a shorter pseudorange) gives Z = -tau c / f_code, slope 1 within 10 % (sampling:
    4 MS/s is ~2 samples per sub-carrier half chip) inside the linear range |tau| < d/2; the BPSK formula's
    gain (1 - d/2) is ~4x too large for BOC(1,1) and the discriminator of BPSK's shape reads tau 3.9x high."""
    taus = np.linspace(-0.4, 0.4, 9) * d / 2
    z = []
    for tau in taus:
        ae, al, _ = _epoch_el(fs, tau, d)
        z.append(code_disc_boc_m(ae, al, d, E1_CHIP_RATE))
        assert np.isclose(z[-1], float(code_discriminator_boc(ae, al, d, E1_CHIP_RATE)), rtol=1e-12, atol=1e-9)
    z = np.array(z)
    truth = -taus * M_PER_CHIP
    slope = np.polyfit(truth, z, 1)[0]
    assert 0.9 < slope < 1.1, slope
    assert np.all(np.sign(z[taus != 0]) == np.sign(truth[taus != 0]))
    # (the BPSK discriminator on the same correlations: the gain of the wrong shape)
    ae, al, _ = _epoch_el(fs, taus[-1], d)
    bpsk = float(code_discriminator(ae, al, d, E1_CHIP_RATE))
    assert bpsk / truth[-1] > 3.0


def test_boc_gain_formula_is_the_triangle_slope():
    """The gain (2 - 3 d) / 6 is what a BOC(1,1) main peak R = 1 - 3|tau| gives: exact at any tau < d/2."""
    d = 0.2
    for tau in (0.01, 0.05, 0.09):
        e, l = 1 - 3 * (d / 2 - tau), 1 - 3 * (d / 2 + tau)
        assert np.isclose(code_disc_boc_m(e, l, d, E1_CHIP_RATE), -tau * M_PER_CHIP, rtol=1e-12)


FS = 4.0e6
DF, CP0, OFF, TAU = 23.0, 0.0, 7, 0.03
CN0 = 45.0


@pytest.fixture(scope="module")
def e1_signal():
    """0.8 s of E1 (E1-B + E1-C, CS25 phase OFF) at 45 dB-Hz, carrier DF Hz, code TAU chips ahead of CP0."""
    rng = np.random.default_rng(11)
    n = int(0.8 * FS)
    t = np.arange(n) / FS
    chips = CP0 + TAU + t * E1_CHIP_RATE
    per = np.floor((chips - TAU) / E1_CODE_LEN).astype(np.int64)      # the period the replica is in
    half = np.floor(2.0 * chips).astype(np.int64) % 8184
    sym = rng.choice([-1.0, 1.0], size=per[-1] + 2)
    cs = cs25_signs()
    a = np.sqrt(2 * 10 ** (CN0 / 10) / FS)           # C/N0 against unit-variance I and Q noise
    s = a / np.sqrt(2) * (boc11(e1b_code(PRN))[half] * sym[per] - boc11(e1c_code(PRN))[half] * cs[(per + OFF) % 25])
    x = s * np.exp(2j * np.pi * (DF * t + 0.3)) + rng.standard_normal(n) + 1j * rng.standard_normal(n)
    return x.astype(np.complex64), sym


def test_gal_epoch_measures_the_signal(e1_signal):
    x, sym = e1_signal
    trk = types.SimpleNamespace(lock_cn0_min_dbhz=25.0, lost_ms=200, cn0_window_ms=100)
    ch = GalTrack(PRN, FS, 0.0, 0, CP0, 0.0, OFF, trk)
    ch.set_external(True, True)                       # the state row as the vector loop steps it
    st, cf, code = ch.st, ch.cfg, ch.code_ext
    o = np.zeros(K.N_OUT)
    halves = np.zeros(4)
    df, z, p1, per, cn0 = [], [], [], [], []
    while gal_epoch(x, 0, st, cf, code, o, halves):
        t_int = (st[K.S_NEXT_SAMPLE] - o[K.O_SAMPLE]) / FS
        df.append(freq_disc_hz(halves[0], halves[1], halves[2], halves[3], t_int))
        z.append(code_disc_boc_m(o[K.O_E], o[K.O_L], cf[K.C_EL_SPACING], E1_CHIP_RATE))
        p1.append(o[K.O_P1I])
        per.append(int(o[K.O_PERIOD]))
        cn0.append(o[K.O_CN0])
        assert o[K.O_INT_MS] == 4 and o[K.O_STATE] == STATE_BIT_SYNC
    assert len(per) >= 195 and np.all(np.diff(per) == 1)
    assert abs(np.mean(df) - DF) < 1.0                      # the halves' cross/dot: signal minus NCO
    assert abs(np.mean(z) + TAU * M_PER_CHIP) < 0.1 * TAU * M_PER_CHIP     # code leads: shorter pseudorange
    # E1-B referred to the pilot: a transmitted +1 symbol reads negative (E1-C is sent as -e_C)
    assert np.all(np.sign(p1) == -sym[np.array(per)])
    # the simulated C/N0 less the prompt's losses: the code offset (BOC(1,1) peak 1 - 3 TAU) and the carrier
    # offset over 4 ms (sinc); the mean of the estimator's windows (25 epochs each)
    loss_db = 20 * np.log10((1 - 3 * TAU) * np.sinc(DF * 4e-3))
    est = np.unique(np.array(cn0)[np.array(cn0) > 0])
    assert len(est) >= 6 and abs(np.mean(est) - (CN0 + loss_db)) < 0.7


def test_handed_back_channel_locks_again(e1_signal):
    """Scalar (0.3 s) -> vector epochs with fixed NCO commands (0.2 s) -> scalar again: the PLL pulls in from the
    last carrier command and locks, the DLL holds the code, the code periods continue without a gap."""
    x, _ = e1_signal
    trk = types.SimpleNamespace(lock_cn0_min_dbhz=25.0, lost_ms=200, cn0_window_ms=100)
    ch = GalTrack(PRN, FS, 0.0, 0, CP0 + TAU, DF + 2.0, OFF, trk)
    r1 = ch.process(x[:int(0.3 * FS)], 0)
    assert r1["pll_lock"][-1] == 1
    ch.set_external(True, True)
    assert ch.st[K.S_CODE_RATE] > 0 and ch.cfg[K.C_CODE_EXTERNAL] == 1
    o, halves = np.zeros(K.N_OUT), np.zeros(4)
    last = None
    while ch.next_sample < 0.5 * FS and gal_epoch(x, 0, ch.st, ch.cfg, ch.code_ext, o, halves):
        last = int(o[K.O_PERIOD])
    ch.set_external(False, False)
    assert ch.cfg[K.C_CARRIER_EXTERNAL] == 0 and not ch.lost
    r2 = ch.process(x, 0)
    assert int(r2["code_period"][0]) == last + 1 and np.all(np.diff(r2["code_period"]) == 1)
    assert r2["state"][0] == 0 and r2["pll_lock"][-1] == 1            # a new pull-in, then phase lock
    tail = r2[-25:]                   # (the code error of one 4-ms epoch at 45 dB-Hz: sigma ~0.016 chip)
    assert abs(np.mean(tail["code_err_chips"])) < 0.01 and np.all(np.abs(tail["code_err_chips"]) < 0.07)
    assert np.all(np.abs(tail["doppler_hz"] - DF) < 3.0)
