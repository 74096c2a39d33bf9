"""Scalar tracking channel: one satellite, numba epoch kernel, NCOs commandable from outside.

A :class:`Channel` is created from an acquisition result and consumes blocks of samples:
``records = channel.process(block, block_start)`` returns the channel-epoch records
(:data:`receiver.record.EPOCH_DTYPE`) of all epochs that fit in the block.  With the built-in PLL and no
external commands the whole block runs in one compiled call, and so it does with another carrier loop
that has a compiled path (CarrierLoop.compiled; receiver/tracking/loops/runner.py runs it: every built-in
variant and any plugin that has one).  A vector loop
(or a carrier loop without a compiled twin) steps the channel epoch by epoch with
``process(..., max_epochs=1)`` and sets the NCOs between epochs with :meth:`Channel.command`.
"""
from __future__ import annotations

import numpy as np

from ..runfile import record
from .correlator import extend_code
from .correlator import CODE_PAD
from ..gnss.signals import GPS_L1CA
from . import kernel as K
from .carrier import channel_variant, make_carrier_loop
from .loops import runner as LR

#: tracking.cn0_estimator: name -> the kernel's C_CN0_EST code
CN0_ESTIMATORS = {"snv": 0, "m2m4": 1}


class Channel:
    """One scalar tracking channel of a PRN (DLL and carrier loop, the epochs in the compiled kernel) from an
    acquisition at file sample index ``sample_index``; its state array ``st`` holds the kernel's S_* slots."""
    def __init__(self, prn: int, doppler_hz: float, code_phase_chips: float, sample_index: int,
                 trk_cfg, fs: float, if_hz: float, channel_id: int = 0, signal=None, weak: bool = False):
        sig = self.signal = signal if signal is not None else GPS_L1CA
        self.prn = prn
        self.id = channel_id
        self.fs = fs
        self.if_hz = if_hz
        self.cfg_section = trk_cfg
        car = trk_cfg.carrier
        dataless = bool(car["dataless"]) if "dataless" in car else False
        nh = sig.secondary(prn)
        bit_ms, self.max_int_ms, weak_int = integration_plan(sig, prn, trk_cfg, dataless, nh)
        self.code_ext, nh_base = code_table(sig.code(prn), nh)
        self.hist = np.zeros(max(20, bit_ms), np.int64)      # sign changes per code period of a bit / overlay
        self._carrier_loop(car, weak, trk_cfg)
        self.cfg = kernel_config(trk_cfg, sig, fs, if_hz, self.max_int_ms, bit_ms, nh_base, dataless, weak_int)
        self.vector_carrier = self.vector_code = False
        self.set_external(False, False)
        self.st = initial_state(sig, doppler_hz, code_phase_chips, sample_index, fs, if_hz,
                                weak and trk_cfg.weak.enabled)
        self.loop.start(doppler_hz, 1e-3)
        self._out = np.zeros((1, K.N_OUT))

    def _carrier_loop(self, car, weak, trk_cfg):
        """The carrier loop object and, when it has one, its compiled path.

        The loop's compiled path (CarrierLoop.compiled: two compiled functions and their parameter / state
        arrays) runs inside the compiled epoch loop (loops/runner.py); the Python object steps epoch by
        epoch when use_compiled_loop is False (the reference, for tests) or the loop has no compiled path.
        """
        self.loop = make_carrier_loop(channel_variant(car, weak), trk_cfg)
        twin = None if self.loop.builtin else self.loop.compiled()
        self.use_compiled_loop = twin is not None
        self._start_fn = self._update_fn = self._lp = self._ls = None
        if twin is not None:
            self._start_fn, self._update_fn, self._lp, self._ls = LR.loop_functions(twin)
        self._cs = np.zeros(LR.N_CS)                 # the channel's side of the hand-over (compiled path)
        self._py_loop_started = False

    # ---------------------------------------------------------------- state
    @property
    def next_sample(self) -> int:
        """File sample index of the next epoch's first sample."""
        return int(self.st[K.S_NEXT_SAMPLE])

    @property
    def lost(self) -> bool:
        """Whether the kernel declared the channel lost."""
        return self.st[K.S_MODE] == K.MODE_LOST

    @property
    def doppler_hz(self) -> float:
        """Carrier Doppler (Hz): the carrier NCO frequency minus the IF."""
        return self.st[K.S_CARR_FREQ] - self.if_hz

    @property
    def cn0_dbhz(self) -> float:
        """The kernel's C/N0 estimate (dB-Hz)."""
        return self.st[K.S_CN0]

    @property
    def bit_offset(self) -> int:
        """Code period (modulo 20) at a data-bit edge, -1 unknown."""
        return int(self.st[K.S_BIT_OFFSET])

    @property
    def dll_hold_s(self) -> float:
        """Seconds after the pull-in during which the DLL keeps a wider bandwidth than its tracking one (a weak
        channel: tracking.weak.dll_hold_ms; else 0); navigation.settle_s counts from then."""
        return self.cfg[K.C_WEAK_DLL_HOLD_MS] * 1e-3 if self.st[K.S_WEAK] > 0 and self.cfg[K.C_WEAK_DLL_BW] > 0 \
            else 0.0

    @property
    def _loop_started(self) -> bool:
        if self.use_compiled_loop:
            return bool(self._cs[LR.CS_STARTED])
        return self._py_loop_started

    @property
    def stepped(self) -> bool:
        """True when Python must see every epoch (Python carrier loop or outside NCO control)."""
        return self.vector_carrier or self.vector_code or not self.loop.builtin

    # ---------------------------------------------------------------- commands
    def set_external(self, carrier: bool, code: bool):
        """Hand the carrier / code NCO to an outside controller (vector loop) or take them back."""
        self.vector_carrier = carrier
        self.vector_code = code
        # a Python carrier loop takes the NCO over once the built-in FLL/PLL has pulled in and the
        # data-symbol edges are known (see _python_carrier_update)
        self.cfg[K.C_CARRIER_EXTERNAL] = 1.0 if (carrier or (not self.loop.builtin and self._loop_started)) \
            else 0.0
        self.cfg[K.C_CODE_EXTERNAL] = 1.0 if code else 0.0

    def command(self, doppler_hz: float | None = None, code_rate_hz: float | None = None,
                code_phase_shift_chips: float = 0.0):
        """Set the NCOs for the next epoch (outside control)."""
        if doppler_hz is not None:
            self.st[K.S_CARR_FREQ] = self.if_hz + doppler_hz
            self.st[K.S_PLL_FREQ] = doppler_hz
        if code_rate_hz is not None:
            self.st[K.S_CODE_RATE] = code_rate_hz
        if code_phase_shift_chips:
            self.st[K.S_CODE_PHASE] += code_phase_shift_chips

    # ---------------------------------------------------------------- processing
    def process(self, block: np.ndarray, block_start: int, max_epochs: int | None = None) -> np.ndarray:
        """Run all epochs that fit in block (or at most max_epochs); return EPOCH_DTYPE records."""
        if self.lost:
            return np.zeros(0, record.EPOCH_DTYPE)
        if not self.stepped and max_epochs is None:
            cap = int(len(block) / self.fs * 1000) + 2
            if self._out.shape[0] < cap:
                self._out = np.zeros((cap, K.N_OUT))
            K.repair_state(self.st)              # non-finite C/N0 estimate: reset, not a dead channel
            n = K.track_block(block, block_start, self.st, self.cfg, self.code_ext, self.hist,
                              self._out, cap)
            K.repair_state(self.st)              # (before and after the compiled call)
            return to_records(self._out[:n])
        if self.use_compiled_loop and not self.vector_carrier:
            return self._process_compiled(block, block_start, max_epochs)
        limit = max_epochs if max_epochs is not None else 10 ** 9
        rows = []
        while len(rows) < limit:
            n = K.track_block(block, block_start, self.st, self.cfg, self.code_ext, self.hist,
                              self._out, 1)
            K.repair_state(self.st)
            if n == 0:
                break
            row = self._out[0].copy()
            rows.append(row)
            if not self.loop.builtin and not self.vector_carrier:
                self._python_carrier_update(row)
        if not rows:
            return np.zeros(0, record.EPOCH_DTYPE)
        return to_records(np.array(rows))

    def _process_compiled(self, block, block_start, max_epochs):
        """The carrier loop's compiled twin stepped inside the compiled epoch loop (same epochs and NCO
        commands as the Python stepping below)."""
        cap = int(len(block) / self.fs * 1000) + 2
        if max_epochs is not None:
            cap = min(cap, max_epochs)
        if self._out.shape[0] < cap:
            self._out = np.zeros((cap, K.N_OUT))
        K.repair_state(self.st)
        total = 0
        carrier_hz = float(self.signal.carrier_hz)
        while total < cap:
            n, pending = LR.call_run_epochs(block, block_start, self.st, self.cfg, self.code_ext, self.hist,
                                            self._out[total:], cap - total, self._lp, self._ls, self._cs,
                                            carrier_hz, self._start_fn, self._update_fn)
            total += n
            if not pending:
                break
            K.repair_state(self.st)          # non-finite state: as after every Python-stepped epoch
            LR.call_apply_epoch(self._out[total - 1], self.st, self.cfg, self._lp, self._ls, self._cs,
                                carrier_hz, self._start_fn, self._update_fn)
        K.repair_state(self.st)
        if total == 0:
            return np.zeros(0, record.EPOCH_DTYPE)
        return to_records(self._out[:total])

    def _python_carrier_update(self, row):
        if not self._loop_started:
            # hand-over from the built-in pull-in loop when the integration may grow (bit sync)
            if row[K.O_STATE] != K.MODE_BIT_SYNC:
                return
            self._py_loop_started = True
            self.loop.start(self.st[K.S_CARR_FREQ] - self.if_hz, row[K.O_INT_MS] * 1e-3,
                            rate_hz_s=self.st[K.S_PLL_RATE], carrier_hz=self.signal.carrier_hz)
            self.set_external(self.vector_carrier, self.vector_code)
            return
        # the exact duration of the epoch just processed (sample count / fs)
        self.loop.epoch_s = (self.st[K.S_NEXT_SAMPLE] - row[K.O_SAMPLE]) / self.fs
        res = self.loop.update(row)
        dop, dphase = res if isinstance(res, tuple) else (res, 0.0)
        old = self.st[K.S_CARR_FREQ] - self.if_hz
        self.st[K.S_CARR_FREQ] = self.if_hz + dop
        self.st[K.S_PLL_FREQ] = dop
        if dphase:
            self.st[K.S_CARR_PHASE] += dphase
        if not self.cfg[K.C_CODE_EXTERNAL]:
            # keep the DLL carrier-aided with the new carrier frequency
            cr, fc = self.signal.chip_rate, self.signal.carrier_hz
            self.st[K.S_CODE_RATE] += cr * (dop - old) / fc


def _largest_divisor(n: int, at_most: int) -> int:
    """The largest divisor of n that is <= at_most (>= 1)."""
    return max(d for d in range(1, min(at_most, n) + 1) if n % d == 0)


def integration_plan(sig, prn, trk_cfg, dataless: bool, nh):
    """(bit_ms, max_int_ms, weak_int_ms) of a channel: the data-symbol length in code periods (1 without
    data symbols and overlay) and the longest coherent integrations of the normal and weak loops, which stay
    within a data symbol (with data) or divide the secondary code (dataless with an overlay)."""
    car = trk_cfg.carrier
    bit_ms = sig.bit_ms(prn)
    if dataless and nh is None:
        bit_ms = 1                     # no data symbols: every code period is an "edge"
    t_coh = car["t_coh_ms"] if "t_coh_ms" in car else None
    want = int(t_coh) if t_coh else int(trk_cfg.integration_ms)
    weak_int = int(trk_cfg.weak.integration_ms)
    if not dataless:                   # integrate within a data symbol
        want = _largest_divisor(bit_ms, want)
        weak_int = _largest_divisor(bit_ms, weak_int)
    elif nh is not None:
        want = _largest_divisor(len(nh), want)
        weak_int = _largest_divisor(len(nh), weak_int)
    return bit_ms, want, weak_int


def code_table(code: np.ndarray, nh):
    """(code_ext, nh_base): the code extended for the correlator (receiver.tracking.correlator.extend_code)
    and, with a secondary code nh, an overlay-modulated section appended at index nh_base (0 without)."""
    code_ext = extend_code(code, 20)
    nh_base = 0
    if nh is not None:
        # overlay-modulated section: 20 periods of code x NH, repeated, CODE_PAD chips of wrap in front
        mod = np.concatenate([code * s_ for s_ in nh]).astype(np.float32)
        sec = np.tile(mod, 3)[len(mod) - CODE_PAD:]
        nh_base = len(code_ext)
        code_ext = np.ascontiguousarray(np.concatenate([code_ext, sec]), dtype=np.float32)
    return code_ext, nh_base


def kernel_config(trk_cfg, sig, fs: float, if_hz: float, max_int_ms: int, bit_ms: int, nh_base: int,
                  dataless: bool, weak_int: int) -> np.ndarray:
    """The compiled kernel's configuration array (C_* slots) of a channel."""
    c = np.zeros(K.N_CONFIG)
    c[K.C_FS] = fs
    c[K.C_IF] = if_hz
    c[K.C_CHIP_RATE] = sig.chip_rate
    c[K.C_CARRIER_HZ] = sig.carrier_hz
    c[K.C_CODE_LEN] = sig.code_len
    c[K.C_EL_SPACING] = early_late_spacing(trk_cfg, fs, sig.chip_rate)
    if not trk_cfg.early_late_snap:       # pull-in and weak channels: whole samples (>= the spacing)
        c[K.C_EL_SPACING_WIDE] = early_late_spacing(trk_cfg, fs, sig.chip_rate, snap=True)
    c[K.C_PLL_BW] = trk_cfg.pll_bw_hz
    c[K.C_PLL_ORDER] = trk_cfg.pll_order
    c[K.C_FLL_BW] = trk_cfg.fll_bw_hz
    c[K.C_DLL_BW] = trk_cfg.dll_bw_hz
    c[K.C_DLL_BW_PULL] = trk_cfg.dll_bw_pull_in_hz
    c[K.C_DLL_ORDER] = trk_cfg.dll_order
    c[K.C_PULL_IN_MS] = trk_cfg.pull_in_ms
    c[K.C_MAX_INT_MS] = max_int_ms
    c[K.C_CN0_WIN_MS] = trk_cfg.cn0_window_ms
    c[K.C_LOCK_CN0_MIN] = trk_cfg.lock_cn0_min_dbhz
    c[K.C_LOCK_RATIO] = trk_cfg.lock_ratio_min
    c[K.C_CN0_EST] = CN0_ESTIMATORS[trk_cfg.cn0_estimator]
    c[K.C_LOST_MS] = trk_cfg.lost_ms
    c[K.C_LOST_GRACE_MS] = trk_cfg.lost_grace_ms
    set_presence(c, trk_cfg)
    c[K.C_BIT_MS] = bit_ms
    c[K.C_NH_BASE] = nh_base
    c[K.C_NO_DATA] = 1.0 if dataless else 0.0
    wk = trk_cfg.weak
    if wk.enabled:                     # weak channels (docs: tracking, weak signals); never stricter than above
        c[K.C_WEAK_CN0] = wk.cn0_dbhz
        c[K.C_WEAK_INT_MS] = weak_int
        c[K.C_WEAK_PLL_BW] = min(wk.pll_bw_hz, trk_cfg.pll_bw_hz)
        c[K.C_WEAK_LOCK_RATIO] = min(wk.lock_ratio_min, trk_cfg.lock_ratio_min)
        c[K.C_WEAK_LOCK_CN0] = min(wk.lock_cn0_min_dbhz, trk_cfg.lock_cn0_min_dbhz)
        c[K.C_WEAK_LOCK_MS] = wk.lock_window_ms
        c[K.C_ESYNC_MIN_MS] = wk.bit_sync_ms
        c[K.C_WEAK_DLL_BW] = min(wk.dll_bw_hz, trk_cfg.dll_bw_hz)
        c[K.C_WEAK_FLL_BW] = min(wk.fll_bw_hz, trk_cfg.fll_bw_hz)
        c[K.C_WEAK_GRACE_MS] = wk.lost_grace_ms
        c[K.C_WEAK_DLL_HOLD_MS] = wk.dll_hold_ms
        c[K.C_WEAK_EXIT_CN0] = max(wk.exit_cn0_dbhz, wk.cn0_dbhz) if wk.exit_cn0_dbhz > 0 else 0.0
        c[K.C_WEAK_FADE] = 1.0 if wk.fade else 0.0
        c[K.C_WEAK_NARROW_EL] = 1.0 if wk.narrow_el_after_hold else 0.0
        c[K.C_WEAK_REPULL_FLL_BW] = wk.repull_fll_bw_hz
    return c


def initial_state(sig, doppler_hz: float, code_phase_chips: float, sample_index: int, fs: float,
                  if_hz: float, weak: bool) -> np.ndarray:
    """The kernel's state array (S_* slots) of a channel from an acquisition: pull-in mode, starting at
    the first sample at or after the next code-period start; weak: weak loops from the pull-in on."""
    s = np.zeros(K.N_STATE)
    rate = sig.chip_rate * (1.0 + doppler_hz / sig.carrier_hz)
    step = rate / fs
    k = int(np.ceil((sig.code_len - code_phase_chips) / step))
    s[K.S_NEXT_SAMPLE] = sample_index + k
    s[K.S_CODE_PHASE] = code_phase_chips + k * step - sig.code_len
    s[K.S_CODE_RATE] = rate
    s[K.S_CARR_FREQ] = if_hz + doppler_hz
    s[K.S_PLL_FREQ] = doppler_hz
    s[K.S_INT_MS] = 1
    s[K.S_BIT_OFFSET] = -1
    s[K.S_MODE] = K.MODE_PULL_IN
    if weak:                           # known weak from acquisition: weak loops from the pull-in on
        s[K.S_WEAK] = 1.0
    return s


def set_presence(c: np.ndarray, trk_cfg):
    """The signal-presence test's configuration (tracking.presence) in a channel's config array."""
    p = trk_cfg.presence
    c[K.C_PRES_MS] = p.window_ms
    c[K.C_PRES_FRAC] = 10.0 ** (-p.drop_db / 10.0)
    c[K.C_PRES_CN0] = p.min_cn0_dbhz
    c[K.C_PRES_LOST_MS] = p.lost_ms


def early_late_spacing(trk_cfg, fs: float, chip_rate: float, snap: bool | None = None) -> float:
    """E-L spacing actually used (chips).  With ``tracking.early_late_snap`` the early and late replicas
    sit a whole number of samples from the prompt: with few samples per chip and an unfiltered signal,
    a fractional-sample offset gives a code bias that wanders with the sub-sample phase when the code
    Doppler is small; a whole-sample offset cancels it but widens the spacing at low sample rates (0.79
    chip at 2.6 MS/s), and the wider spacing costs more than the bias: off by default (docs: tracking)."""
    d = float(trk_cfg.early_late_chips)
    if not (trk_cfg.early_late_snap if snap is None else snap):
        return d
    half_samples = max(1, round(0.5 * d * fs / chip_rate))
    return 2.0 * half_samples * chip_rate / fs


def to_records(rows: np.ndarray) -> np.ndarray:
    """Kernel output rows -> EPOCH_DTYPE records."""
    rec = np.zeros(len(rows), record.EPOCH_DTYPE)
    names = record.EPOCH_DTYPE.names
    for j, name in enumerate(names):
        rec[name] = rows[:, j]
    return rec
