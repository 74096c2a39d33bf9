"""Vector tracking: scalar-to-vector handover, variant registry.

The pipeline owns a :class:`Handover` (the handover bookkeeping: the history of scalar fixes) and calls its
``step(start)`` once per chunk while ``vector.enabled`` until it returns a
:class:`~receiver.tracking.vector.tracker.VectorTracker`; from then on the tracker steps every channel.  When
the tracker cannot bridge an outage (``tracker.reinit_needed``: fewer than 4 channels with signal and the
filter's position sigma past ``vector.reinit_sigma_m``) the pipeline calls ``fall_back``: the channels go
back to their scalar loops (the channel manager re-acquires the lost ones) and the handover starts again
from the next scalar fix.

Variants (``vector.variant``; one module each, one line in :data:`REGISTRY`):
  fixed_r     VLL, error-state EKF [r, v, t_b, dt_d], fixed R (fixed_r.py)
  adaptive_r  the same with a sliding-window adaptive R (adaptive_r.py)
  polynomial  VDFLL with polynomial predictive filters and chi-square manoeuvre detection (polynomial.py)
  cv          constant-velocity VDFLL baseline with the paper's per-epoch Q (cv.py)

Handover (``vector.start_s`` seconds after the first sample, default 5 s after the first fix): the filter
starts from the latest scalar fix - position, velocity, clock bias and drift - propagated to the first
vector epoch, and the code-minus-carrier drift is estimated from the history of scalar fixes (the slope of
the clock bias minus the Doppler drift) or, lacking that, from the channels' DLL rate integrators.  The
channels keep their NCO state: the first vector measurements are taken with the scalar NCOs, after which
the vector filter commands them.
"""
from __future__ import annotations

import logging

import numpy as np

from ... import plugins
from ...errors import UserError
from ...gnss.signals import C_LIGHT, CA_CHIP_RATE
from .. import kernel as K
from .adaptive_r import AdaptiveR
from .base import VectorFilter
from .cv import CV
from .fixed_r import FixedR
from .polynomial import PolynomialFilter
from .tracker import VectorTracker

REGISTRY: dict[str, type[VectorFilter]] = {
    "fixed_r": FixedR,
    "adaptive_r": AdaptiveR,
    "polynomial": PolynomialFilter,
    "cv": CV,
}

DEFAULT_DELAY_S = 5.0


def filter_class(name: str) -> type[VectorFilter]:
    """The class of vector variant ``name``: a built-in (:data:`REGISTRY`), an installed plugin (entry point
    ``gnssrx.vector_filters``) or ``module:Class``, checked against the interface (base.py; one-line
    errors)."""
    if name in REGISTRY:
        return REGISTRY[name]
    found = plugins.find("vector_filter", name)
    if found is None:
        avail = list(REGISTRY) + sorted(plugins.entry_points("vector_filter"))
        raise UserError(f"unknown vector variant '{name}' (available: {', '.join(avail)}, or module:Class)")
    cls, pre = found.cls, f"vector filter plugin '{name}'"
    if not issubclass(cls, VectorFilter):
        raise UserError(f"{pre}: {cls.__name__} is not a receiver.tracking.vector.base.VectorFilter")
    if not isinstance(cls.name, str) or not cls.name.isidentifier() or cls.name == VectorFilter.name:
        raise UserError(f"{pre}: its class attribute name must be an identifier, got {cls.name!r}")
    for method in ("matrices", "initial", "layout"):
        if getattr(cls, method, None) is getattr(VectorFilter, method):
            raise UserError(f"{pre}: missing method {method}")
    if type(getattr(cls, "n", None)) is type(VectorFilter.n) and cls.n is VectorFilter.n:
        raise UserError(f"{pre}: missing property n")
    plugins.check_params(pre, getattr(cls, "PARAMS", {}))
    return cls


def make_filter(name: str, vcfg) -> VectorFilter:
    """The vector filter of variant ``name`` (built-in or plugin) for the vector section, at its
    integration time (s); a motion model the variant cannot take is a UserError."""
    cls = filter_class(name)
    filt = cls(vcfg, int(vcfg.integration_ms) * 1e-3)
    if vcfg.motion_model != "cv" and not filt.selectable_motion:
        raise UserError(f"vector.motion_model '{vcfg.motion_model}' applies to fixed_r and adaptive_r only "
                        f"(variant '{name}' has its own model)")
    return filt


_log = logging.getLogger(__name__).info      # vector handover / re-initialisation messages


def code_carrier_drift(history, channels) -> float:
    """Code drift minus carrier drift (m/s) from scalar fixes [(sample_time_s, bias_m, drift_mps)], else
    from the DLL rate integrators (chips/s) of the channels; 0 when neither is available."""
    if len(history) >= 5 and history[-1][0] - history[0][0] >= 2.0:
        t = np.array([h[0] for h in history])
        b = np.array([h[1] for h in history])
        d = np.array([h[2] for h in history])
        ok = np.isfinite(b) & np.isfinite(d)
        if ok.sum() >= 5:
            slope = np.polyfit(t[ok] - t[ok][0], b[ok], 1)[0]
            return float(slope - np.median(d[ok]))
    # (chips/s of each channel's signal, referred to L1 C/A's chip rate: a factor of exactly 1 for GPS)
    rates = [ch.st[K.S_DLL_RATE] * (CA_CHIP_RATE / ch.signal.chip_rate) for ch in channels.values()
             if ch.st[K.S_MODE] in (K.MODE_TRACK, K.MODE_BIT_SYNC) and ch.st[K.S_LOCK] > 0]
    if rates:
        return float(-C_LIGHT * np.median(rates) / CA_CHIP_RATE)
    return 0.0


class Handover:
    """Scalar-to-vector handover state of one run (history of scalar fixes, re-initialisations)."""

    def __init__(self, cfg, channels, nav, fs, log=None, signals=None):
        """channels: the run's channel table (receiver.tracking.table.ChannelTable, keyed like the
        navigation engine's channels); signals: [(SignalDef, IF Hz)] in the order of the blocks the tracker is given
        (None: GPS L1 C/A alone)."""
        if nav is None:
            raise UserError("vector tracking needs the navigation solution (navigation.enabled: true)")
        make_filter(cfg.vector.variant, cfg.vector)     # validate early
        self.cfg, self.channels, self.nav, self.fs = cfg, channels, nav, fs
        self.signals = signals
        self.log = log or _log
        self.state = {"history": [], "first": None, "last": None, "not_before": None}
        self.reinits = 0

    def step(self, start):
        """The vector tracker once the handover time is reached and a scalar fix is available, else None."""
        return handover(self.cfg, self.channels, self.nav, start, self.fs, log=self.log, state=self.state,
                        signals=self.signals)

    def fall_back(self, tracker, start):
        """The tracker cannot bridge the outage: every channel that still carries signal back to its scalar
        loop, the others closed as lost (the channel manager re-acquires them around the prediction: handed
        back in the outage, a channel's loops would hold noise -- its weak loops' lock detectors read noise
        at 20-ms integration as ~20 dB-Hz and fed aided fixes hundreds of metres off); the next handover
        waits for a scalar fix computed after this moment."""
        cfg = self.cfg
        for prn in list(tracker.prns):
            ch = self.channels.get(prn)
            carries = tracker._vector_lock(prn)
            tracker._remove(prn, not carries)
            if ch is not None and carries:
                _scalar_again(cfg, ch)
        self.reinits += 1
        self.state["not_before"] = start
        self.log(f"vector: outage longer than the filter can bridge at {start / self.fs:.2f} s: scalar "
                 f"tracking until the next scalar fix, then a new handover")
        return None


def _scalar_again(cfg, ch):
    ch.set_external(False, False)
    ch.cfg[K.C_LOST_MS] = cfg.tracking.lost_ms
    ch.cfg[K.C_PRES_LOST_MS] = cfg.tracking.presence.lost_ms
    ch.cfg[K.C_CN0_EST] = {"snv": 0, "m2m4": 1}[cfg.tracking.cn0_estimator]
    ch.cfg[K.C_MAX_INT_MS] = getattr(ch, "max_int_ms", cfg.tracking.integration_ms)    # its own (B1I D2: 2 ms)
    ch.cfg[K.C_CN0_WIN_MS] = cfg.tracking.cn0_window_ms


def handover(cfg, channels, nav, start, fs, log=_log, state=None, signals=None):
    """The vector tracker once the handover time is reached and a scalar fix is available, else None.
    state: the handover bookkeeping (Handover.state), kept by the caller between calls."""
    v = cfg.vector
    if nav is None:
        raise UserError("vector tracking needs the navigation solution (navigation.enabled: true)")
    make_filter(v.variant, v)                       # validate early
    st = state if state is not None else {"history": [], "first": None, "last": None, "not_before": None}
    lf = nav.last_fix
    if lf is not None and (st["last"] is None or lf[0] != st["last"]):
        s_fix, fix = lf
        st["last"] = s_fix
        st["history"].append((s_fix / fs, fix.clock_bias_m, fix.clock_drift_mps))
        del st["history"][:-600]
        if st["first"] is None:
            st["first"] = s_fix
    first_sample = int(round(cfg.input.skip_s * fs))
    if v.start_s is not None:
        if start < first_sample + v.start_s * fs:
            return None
    elif st["first"] is None or start < st["first"] + DEFAULT_DELAY_S * fs:
        return None
    if lf is None:
        return None
    s_fix, fix = lf
    if start - s_fix > 2.0 * fs:                     # no recent fix (scalar positioning lost): wait
        return None
    if st.get("not_before") is not None and s_fix < st["not_before"]:
        return None                                 # after a fall-back: wait for a new scalar fix
    vel = np.asarray(fix.velocity_ecef, dtype=float)
    drift = float(fix.clock_drift_mps)
    sig_v = float(v.init_sigma_vel_mps)
    if not (np.all(np.isfinite(vel)) and np.isfinite(drift)):
        vel, drift, sig_v = np.zeros(3), 0.0, 50.0
    hist = [h for h in st["history"] if h[0] <= s_fix / fs + 1e-9]
    delta = code_carrier_drift(hist, channels) if v.code_carrier_drift else 0.0
    filt = make_filter(v.variant, v)
    sig = {"pos": float(v.init_sigma_pos_m), "vel": sig_v, "b": float(v.init_sigma_pos_m),
           "d": sig_v, "delta": 1.0}
    tracker = VectorTracker(cfg, channels, nav, filt, fs, s_fix, fix.rx_tow,
                            (np.asarray(fix.ecef, dtype=float), vel, float(fix.clock_bias_m), drift, delta),
                            sig, start, log=log, signals=signals, isb=getattr(fix, "isb_m", None))
    if len(tracker.prns) < 4:
        # undo: give the NCOs back to the scalar loops and try again next chunk
        for prn in list(tracker.prns):
            ch = channels[prn]
            tracker._remove(prn, False)
            _scalar_again(cfg, ch)
        return None
    isb = "".join(f"; inter-system bias {c} {tracker.x[i]:+.2f} m" for c, i in tracker.isb_index.items())
    log(f"vector: handover at {start / fs - first_sample / fs:.2f} s to {filt.describe()}; "
        f"{len(tracker.prns)} channels {' '.join(tracker.label(p) for p in tracker.prns)}; "
        f"code-carrier drift {delta:+.2f} m/s{isb}")
    return tracker
