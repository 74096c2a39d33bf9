"""The channel's compiled epoch loop for any carrier loop with a compiled path (built-in or plugin).

A carrier loop's compiled path is two numba functions with fixed signatures (:data:`START_SIG`,
:data:`UPDATE_SIG`) working on two float64 arrays the loop packs once per channel: ``lp`` (its parameters)
and ``ls`` (its state).  :func:`run_epochs` runs a channel's epochs over a block and calls them between
epochs, as ``Channel.process`` does from Python with the loop object (hand-over from the built-in pull-in
loop at bit sync, the exact epoch duration from the sample count, NCO frequency and phase step,
carrier-aided DLL).  The two functions reach it as first-class function values (numba FunctionType):
one machine-code copy of the runner, cached on disk once, serves every loop, and a loop's own module can
change without the runner's cache going stale.

What the channel owns (``st``, ``cfg`` and ``cs`` here): the NCOs, the DLL, the lock detectors and C/N0
estimate, the epoch timing and the moment of the hand-over (``cs[CS_STARTED]``).  What the loop owns:
``lp`` and ``ls``, entirely; it returns the Doppler of the next epoch and a phase step, and reads nothing
else of the channel.
"""
from __future__ import annotations

import numpy as np
from numba import njit, types
from numba.experimental.function_type import _get_wrapper_address

from .. import kernel as K
from ..correlator import workspace

_f8 = types.float64
_arr = types.float64[::1]
#: start(lp, ls, doppler_hz, T_s, rate_hz_s, carrier_hz) -> None: the loop takes the carrier over
START_SIG = types.void(_arr, _arr, _f8, _f8, _f8, _f8)
#: update(lp, ls, prompt_i, prompt_q, T_s, p1_i, p1_q, p2_i, p2_q) -> (doppler_hz of the next epoch,
#: NCO phase step in cycles)
UPDATE_SIG = types.UniTuple(_f8, 2)(_arr, _arr, _f8, _f8, _f8, _f8, _f8, _f8, _f8)
START_T = types.FunctionType(START_SIG)
UPDATE_T = types.FunctionType(UPDATE_SIG)

CS_STARTED = 0          # channel-side loop state: 1 once the loop has the carrier
N_CS = 1


@njit(cache=True, nogil=True)
def apply_epoch(row, st, cfg, lp, ls, cs, carrier_hz, start, update):
    """After one epoch (its output row): the hand-over at bit sync, or the loop's update and the NCO
    commands (Channel._python_carrier_update)."""
    if cs[CS_STARTED] == 0.0:
        if row[K.O_STATE] != K.MODE_BIT_SYNC:
            return
        start(lp, ls, st[K.S_CARR_FREQ] - cfg[K.C_IF], row[K.O_INT_MS] * 1e-3, st[K.S_PLL_RATE], carrier_hz)
        cs[CS_STARTED] = 1.0
        cfg[K.C_CARRIER_EXTERNAL] = 1.0
        return
    T = (st[K.S_NEXT_SAMPLE] - row[K.O_SAMPLE]) / cfg[K.C_FS]
    if T == 0.0:
        T = row[K.O_INT_MS] * 1e-3
    dop, dphase = update(lp, ls, row[K.O_PI], row[K.O_PQ], T, row[K.O_P1I], row[K.O_P1Q],
                         row[K.O_P2I], row[K.O_P2Q])
    old = st[K.S_CARR_FREQ] - cfg[K.C_IF]
    st[K.S_CARR_FREQ] = cfg[K.C_IF] + dop
    st[K.S_PLL_FREQ] = dop
    if dphase != 0.0:
        st[K.S_CARR_PHASE] += dphase
    if cfg[K.C_CODE_EXTERNAL] == 0:
        st[K.S_CODE_RATE] += cfg[K.C_CHIP_RATE] * (dop - old) / cfg[K.C_CARRIER_HZ]


@njit(cache=True, nogil=True)
def run_epochs(samples, block_start, st, cfg, code_ext, hist, out, max_epochs, lp, ls, cs, carrier_hz, start,
               update):
    """Epochs while they fit in the block (at most max_epochs), the carrier loop stepped between them.
    Returns (epochs written, pending): pending = 1 when the state became non-finite after the last epoch
    written: the caller repairs it (kernel.repair_state) and then calls apply_epoch on that row."""
    n_out = 0
    ws = workspace()
    while n_out < max_epochs:
        n = K.track_block_ws(samples, block_start, st, cfg, code_ext, hist, out[n_out:n_out + 1], 1, ws)
        if n == 0:
            break
        n_out += 1
        for i in range(st.shape[0]):
            if not np.isfinite(st[i]):
                return n_out, 1
        apply_epoch(out[n_out - 1], st, cfg, lp, ls, cs, carrier_hz, start, update)
    return n_out, 0


class CompiledFunction:
    """A compiled loop function as a first-class function value of signature ``sig`` (its machine-code
    address, looked up once)."""

    def __init__(self, fn, sig):
        if not hasattr(fn, "get_compile_result"):
            raise TypeError(f"{fn!r} is not a numba-compiled function")
        if tuple(sig.args) not in fn.overloads:
            fn.compile(sig.args)
        self.fn, self.sig = fn, sig
        self._addr = _get_wrapper_address(fn, sig)

    def __wrapper_address__(self):
        return self._addr


_ENTRIES: dict = {}
_WRAPPED: dict = {}


def _wrap(fn, sig) -> CompiledFunction:
    if isinstance(fn, CompiledFunction):
        return fn
    w = _WRAPPED.get((fn, sig))
    if w is None:
        w = _WRAPPED[(fn, sig)] = CompiledFunction(fn, sig)
    return w


def _entry(dispatcher, args):
    """The compiled specialisation of ``dispatcher`` for these arrays (loaded from numba's cache), whose
    last two arguments are the loop's start / update function values."""
    key = (dispatcher,) + tuple((a.dtype.str, a.ndim, a.flags.c_contiguous) if isinstance(a, np.ndarray)
                                else type(a) for a in args)
    e = _ENTRIES.get(key)
    if e is None:
        from numba import typeof
        sig = tuple(typeof(a) for a in args) + (START_T, UPDATE_T)
        dispatcher.compile(sig)
        e = _ENTRIES[key] = dispatcher.overloads[sig].entry_point
    return e


def call_run_epochs(samples, block_start, st, cfg, code_ext, hist, out, max_epochs, lp, ls, cs, carrier_hz,
                    start: CompiledFunction, update: CompiledFunction):
    """The compiled ``run_epochs`` kernel for these arguments, called with the loop's compiled start/update
    (its entry point cached per signature)."""
    args = (samples, block_start, st, cfg, code_ext, hist, out, max_epochs, lp, ls, cs, carrier_hz)
    return _entry(run_epochs, args)(*args, start, update)


def call_apply_epoch(row, st, cfg, lp, ls, cs, carrier_hz, start: CompiledFunction, update: CompiledFunction):
    """The compiled ``apply_epoch`` kernel for these arguments, called with the loop's compiled start/update
    (its entry point cached per signature)."""
    args = (row, st, cfg, lp, ls, cs, carrier_hz)
    return _entry(apply_epoch, args)(*args, start, update)


def loop_functions(twin):
    """(start, update, lp, ls) of a loop's ``compiled()``: the functions as function values (numba
    dispatchers are wrapped), the arrays as contiguous float64."""
    start, update, lp, ls = twin
    start, update = _wrap(start, START_SIG), _wrap(update, UPDATE_SIG)
    return (start, update, np.ascontiguousarray(lp, dtype=np.float64),
            np.ascontiguousarray(ls, dtype=np.float64))
