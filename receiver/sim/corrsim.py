"""Correlator-level simulator: prompt I/Q at the integration rate, generated from truth, closed around a
carrier loop.  For Monte Carlo sweeps of the carrier loops (scintillation, weak signals) without IF samples.

Model.  Truth on a grid of DT = 0.5 ms: carrier phase theta(t) (cycles) = line-of-sight dynamics + receiver
oscillator phase noise (h0, h_-2) + scintillation phase / 2 pi; amplitude a(t) = sqrt(2 C/N0(t) DT) |z(t)|
(|z|: scintillation amplitude, mean power 1).  One epoch of m ms is 2m grid steps; the NCO runs at phase
p + f tau (cycles, tau from the epoch start).  Per grid step i (midpoint values):

    c_i = a_i exp(j 2 pi (theta_i - p - f tau_i)) sinc((theta'_i - f) DT) + n_i,   n_i ~ CN(0, 2)

(unit noise variance per component per step), prompt P = sum_i c_i, halves P1 / P2 = first / second m
steps -- so that C/N0 T = |signal|^2 / (2 var) per epoch, as in the IF correlator with perfect code
tracking.  The loop's returned (Doppler, phase step) set the NCO of the next epoch.  Truth phase error of an
epoch: theta(t_mid) - NCO(t_mid).

Scintillation uses the simulator's Cornell model (receiver.sim.scintillation) on a 1 ms grid, so the
correlator-level and IF-level runs share the same scintillation statistics.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..gnss.clock import OSCILLATORS
from ..gnss.signals import C_LIGHT

DT = 0.5e-3
G0 = 9.80665


@dataclass
class CorrScenario:
    """One correlator-level scenario: duration (s), coherent integration (ms), carrier (Hz), C/N0 (dB-Hz, constant
    or a linear schedule), scintillation S4 / sigma_phi (rad) / tau0 (s), receiver oscillator h0 / h_-2,
    line-of-sight dynamics (static or manoeuvre up to accel_g g), true Doppler and the loop's initial error (Hz),
    seed."""
    duration_s: float = 120.0
    t_coh_ms: int = 5
    carrier_hz: float = 1561.098e6
    cn0_dbhz: float = 40.0
    cn0_schedule: tuple | None = None          # ((t_s...), (dbhz...)) linear, overrides cn0_dbhz
    s4: float = 0.0
    sigma_phi: float = 0.0
    tau0_s: float = 0.5
    h0: float = OSCILLATORS["tcxo"][0]         # receiver oscillator (TCXO)
    h_2: float = OSCILLATORS["tcxo"][2]
    dynamics: str = "static"                   # static | manoeuvre
    accel_g: float = 2.0
    doppler_hz: float = 0.0
    seed: int = 1
    init_doppler_err_hz: float = 1.0
    extra: dict = field(default_factory=dict)


def los_accel(t, accel_g=2.0, start=5.0, period=10.0, ramp=1.0, hold=3.0):
    """Manoeuvre profile (m/s^2 along the line of sight): from `start`, every `period` s a ramp of `ramp` s
    up to accel_g g, `hold` s at it, `ramp` s back to 0, alternating sign from one period to the next."""
    a = np.zeros_like(t)
    tt = t - start
    on = tt >= 0
    k = np.floor(tt / period)
    u = tt - k * period
    amp = accel_g * G0 * np.where(k % 2 == 0, 1.0, -1.0)
    prof = np.clip(u / ramp, 0, 1) * (u < ramp + hold) + \
        np.clip(1.0 - (u - ramp - hold) / ramp, 0, 1) * (u >= ramp + hold)
    a[on] = (amp * prof)[on]
    return a


def make_truth(sc: CorrScenario):
    """Truth on the DT grid: (t, theta cycles, amplitude a, scint amplitude, scint phase rad, cn0 dB-Hz)."""
    rng = np.random.default_rng(np.random.SeedSequence([sc.seed, 11]))
    n = int(round(sc.duration_s / DT)) + 2
    t = np.arange(n) * DT
    theta = sc.doppler_hz * t
    if sc.dynamics == "manoeuvre":
        acc = los_accel(t, sc.accel_g)
        vel = np.cumsum(acc) * DT
        rng_m = np.cumsum(vel) * DT
        theta = theta + rng_m * sc.carrier_hz / C_LIGHT
    elif sc.dynamics != "static":
        raise ValueError(f"unknown dynamics {sc.dynamics}")
    # oscillator: fractional frequency y = white FM + random-walk FM; phase = fc * integral(y)
    if sc.h0 > 0 or sc.h_2 > 0:
        y = rng.standard_normal(n) * math.sqrt(sc.h0 / (2.0 * DT))
        y += np.cumsum(rng.standard_normal(n)) * math.sqrt(2.0 * math.pi ** 2 * sc.h_2 * DT)
        theta = theta + sc.carrier_hz * np.cumsum(y) * DT
    s_amp = np.ones(n)
    s_ph = np.zeros(n)
    if sc.s4 > 0 or sc.sigma_phi > 0:
        from .scintillation import Scintillation
        srng = np.random.default_rng(np.random.SeedSequence([sc.seed, 12]))
        ms = int(math.ceil(n * DT / 1e-3)) + 2
        sci = Scintillation(sc.s4, sc.sigma_phi, sc.tau0_s, 1e-3, srng, window_s=60.0)
        amp, ph = sci.take(ms)
        tm = np.arange(ms) * 1e-3
        s_amp = np.interp(t, tm, amp)
        s_ph = np.interp(t, tm, ph)
        theta = theta + s_ph / (2.0 * math.pi)
    if sc.cn0_schedule is not None:
        cn0 = np.interp(t, np.asarray(sc.cn0_schedule[0], float), np.asarray(sc.cn0_schedule[1], float))
    else:
        cn0 = np.full(n, float(sc.cn0_dbhz))
    a = np.sqrt(2.0 * 10 ** (cn0 / 10.0) * DT) * s_amp
    return t, theta, a, s_amp, s_ph, cn0


OUT_KEYS = ("t", "ip", "qp", "err_cycles", "cn0_true", "cn0_est", "doppler", "doppler_true")


def prepare(sc: CorrScenario, truth=None):
    """The arrays one run of :func:`run` works on (shared with the compiled driver
    receiver.evaluate.corrloop): a dict with the truth arrays t, theta, cn0, the half-step midpoints th_mid,
    fr (true frequency), a_mid, the per-epoch complex noise (n_ep x 2m, drawn from the scenario's seed),
    tau (step midpoints in an epoch), m (steps per half epoch = t_coh_ms), T, n_ep, f_true0 and the phase
    offset that starts the loop's NCO model at zero phase error."""
    if truth is None:
        truth = make_truth(sc)
    t, theta, a, s_amp, s_ph, cn0 = truth
    m = int(sc.t_coh_ms)
    steps = 2 * m
    n_ep = (len(t) - 2) // steps
    rng = np.random.default_rng(np.random.SeedSequence([sc.seed, 13]))
    noise = (rng.standard_normal((n_ep, steps)) + 1j * rng.standard_normal((n_ep, steps)))
    fr = np.diff(theta) / DT
    return {"t": t, "theta": theta, "cn0": cn0, "th_mid": 0.5 * (theta[1:] + theta[:-1]), "fr": fr,
            "a_mid": 0.5 * (a[1:] + a[:-1]), "noise": noise, "tau": (np.arange(steps) + 0.5) * DT, "m": m,
            "T": m * 1e-3, "n_ep": n_ep, "f_true0": fr[0],
            # the loop's NCO model starts at phase 0; align the truth so that the initial phase error is 0
            "offset": theta[0]}


def run(loop, sc: CorrScenario, truth=None, record_pli=True):
    """Close `loop` (a started-or-not PythonLoop) around the correlator model.  Returns a dict of per-epoch
    arrays (OUT_KEYS): t (epoch midpoint), ip, qp, err_cycles (truth phase - NCO phase at the midpoint),
    cn0_true, cn0_est (loop's estimate when it has one), doppler (NCO), doppler_true.

    This is the reference path: numpy per epoch and the Python loop's ``step``.  The figure scripts run the
    same model compiled (receiver.evaluate.corrloop.run: the loops' compiled twins, the same noise and the
    same arithmetic; equal records, tests/unit/tracking/test_corrsim_compiled.py) — it lives above the receiver stages
    because the simulator must not depend on them."""
    P = prepare(sc, truth)
    t, theta, cn0, th_mid, fr, a_mid = P["t"], P["theta"], P["cn0"], P["th_mid"], P["fr"], P["a_mid"]
    noise, tau, m, T, n_ep, f_true0, offset = (P["noise"], P["tau"], P["m"], P["T"], P["n_ep"], P["f_true0"],
                                               P["offset"])
    steps = 2 * m
    loop.start(f_true0 + sc.init_doppler_err_hz, T, rate_hz_s=0.0, carrier_hz=sc.carrier_hz)
    out = {k: np.empty(n_ep) for k in OUT_KEYS}
    two_pi_j = 2j * math.pi
    for k in range(n_ep):
        i0 = k * steps
        p, f = loop.nco_phase, loop.nco_freq
        sl = slice(i0, i0 + steps)
        d = th_mid[sl] - offset - p - f * tau
        c = a_mid[sl] * np.exp(two_pi_j * d) * np.sinc((fr[sl] - f) * DT) + noise[k]
        p1 = complex(c[:m].sum())
        p2 = complex(c[m:].sum())
        P = p1 + p2
        ip, qp = P.real, P.imag
        im = i0 + m
        out["t"][k] = t[im]
        out["ip"][k] = ip
        out["qp"][k] = qp
        out["err_cycles"][k] = theta[im] - offset - (p + f * T / 2.0)
        out["cn0_true"][k] = cn0[im]
        out["doppler"][k] = f
        out["doppler_true"][k] = fr[im]
        loop.step(ip, qp, T, p1, p2)
        est = getattr(loop, "cn0", None)
        out["cn0_est"][k] = 10 * math.log10(est) if est else np.nan
    return out


# ---------------------------------------------------------------------------------------------- metrics
def wrap_costas(err_cycles):
    """Phase error folded to (-0.25, 0.25] cycles (Costas ambiguity: half a cycle)."""
    return (np.asarray(err_cycles) + 0.25) % 0.5 - 0.25


def phase_error_std_deg(err_cycles, per_s=60.0, t=None, skip_s=2.0):
    """Standard deviation (deg) of the Costas-folded phase error, about its circular mean, per window of
    per_s seconds (after skip_s).  Returns an array (one value per window)."""
    e = np.asarray(err_cycles)
    if t is None:
        t = np.arange(e.size)
    t = np.asarray(t)
    sel = t >= skip_s
    e, t = e[sel], t[sel]
    out = []
    w0 = t[0] if t.size else 0.0
    nwin = max(1, int(math.floor((t[-1] - w0) / per_s + 1e-9))) if t.size else 0
    for w in range(nwin):
        s = (t >= w0 + w * per_s) & (t < w0 + (w + 1) * per_s)
        if s.sum() < 10:
            continue
        x = e[s]
        mean = np.angle(np.mean(np.exp(4j * math.pi * x))) / (4 * math.pi)   # circular mean, period 0.5
        out.append(float(np.std(wrap_costas(x - mean)) * 360.0))
    return np.array(out)


def loss_of_lock_probability(ip, qp, T, window_s=0.1, threshold=13.56, skip_epochs=0):
    """P(sum I^2 / sum Q^2 < threshold) over consecutive windows of window_s."""
    n = max(1, int(round(window_s / T)))
    i2 = np.asarray(ip)[skip_epochs:] ** 2
    q2 = np.asarray(qp)[skip_epochs:] ** 2
    m = (i2.size // n) * n
    if m == 0:
        return float("nan")
    si = i2[:m].reshape(-1, n).sum(1)
    sq = q2[:m].reshape(-1, n).sum(1)
    return float(np.mean(si < threshold * sq))


def windowed_pli(ip, qp, T, window_s=0.1):
    """Phase lock indicator (sum I^2 - sum Q^2) / (sum I^2 + sum Q^2) of the prompts over consecutive windows of
    window_s (s), one value per whole window (T: epoch length, s)."""
    n = max(1, int(round(window_s / T)))
    i2 = np.asarray(ip) ** 2
    q2 = np.asarray(qp) ** 2
    m = (i2.size // n) * n
    si = i2[:m].reshape(-1, n).sum(1)
    sq = q2[:m].reshape(-1, n).sum(1)
    return (si - sq) / (si + sq)


def tracking_threshold(t, err_cycles, cn0_true, window_s=1.0, max_std_deg=30.0, doppler_err=None,
                       max_freq_hz=None):
    """C/N0 (dB-Hz) where lock is lost for good: the true C/N0 at the end of the last `window_s` window in
    which the loop is in lock (std of the Costas-folded phase error about its circular mean below
    max_std_deg, and, when given, |mean Doppler error| below max_freq_hz).  Returns (threshold,
    locked-per-window array)."""
    t = np.asarray(t)
    n_w = int(math.floor((t[-1] - t[0]) / window_s))
    locked = np.zeros(n_w, bool)
    ends = np.zeros(n_w)
    for w in range(n_w):
        s = (t >= t[0] + w * window_s) & (t < t[0] + (w + 1) * window_s)
        x = np.asarray(err_cycles)[s]
        mean = np.angle(np.mean(np.exp(4j * math.pi * x))) / (4 * math.pi)
        ok = np.std(wrap_costas(x - mean)) * 360.0 < max_std_deg
        if doppler_err is not None and max_freq_hz is not None:
            ok = ok and abs(np.mean(np.asarray(doppler_err)[s])) < max_freq_hz
        locked[w] = ok
        ends[w] = np.asarray(cn0_true)[s][-1]
    if not locked.any():
        return float(np.asarray(cn0_true)[0]), locked
    last = np.flatnonzero(locked)[-1]
    if last == n_w - 1:
        return float(ends[-1]), locked          # never lost: threshold <= final C/N0
    return float(ends[last]), locked


def if_phase_error(run_h5, truth_h5, prn, if_hz=0.0):
    """Phase error of an IF-level run against the simulator truth: per epoch (state bit_sync), the truth
    carrier phase minus the NCO phase at the epoch midpoint (cycles;
    :func:`receiver.runfile.truth.carrier_phase_error`).  Returns (t_mid, err, prompt I, Q, integration s)."""
    from ..gnss.satid import sat_label
    from ..runfile.reader import RunFile
    from ..runfile.truth import TruthFile, carrier_phase_error
    with RunFile(run_h5) as rf:
        name = sat_label(prn, rf.system)
        ch = rf.channel(name, ("state", "time_s", "integration_ms", "carrier_phase_cycles", "doppler_hz",
                               "prompt_i", "prompt_q"))
    with TruthFile(truth_h5) as tf:
        sat = tf.satellite(name, ("time_s", "carrier_phase_cycles", "doppler_hz"))
    sel = ch["state"] == 2
    ch = {k: v[sel] for k, v in ch.items()}
    tm, err = carrier_phase_error(ch, sat, if_hz, at="mid")
    return tm, err, ch["prompt_i"].astype(float), ch["prompt_q"].astype(float), ch["integration_ms"] * 1e-3
