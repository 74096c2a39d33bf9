"""What a carrier-loop plugin imports (the stable names of the extension interface; docs/plugins.md).

    from receiver.tracking.loops.plugin import P, PythonLoop, START_SIG, UPDATE_SIG, nco_command, njit

* :class:`CarrierLoop` - the interface (receiver/tracking/loops/base.py); :class:`PythonLoop` - its
  reference-path base: implement ``init(doppler_hz, rate_hz_s)`` and ``step(ip, qp, T, p1, p2)`` returning
  ``self._command(T, start_phase, freq)``; it keeps the NCO model (``self.nco_phase``, ``self.nco_freq``).
* the compiled path: ``compiled()`` returns ``(start, update, lp, ls)`` with ``start`` / ``update`` numba
  functions of :data:`START_SIG` / :data:`UPDATE_SIG` and ``lp`` / ``ls`` float64 arrays (the loop's
  parameters and its whole state, one pair per channel); :func:`nco_command` is ``_command`` on two slots
  of ``ls``.
* :class:`P` - a parameter of ``PARAMS`` (the loop's config keys, at ``tracking.carrier.<name>``).

The channel owns the NCOs, the DLL, the lock detectors, the C/N0 estimate, the epoch timing and when the
loop takes over (at bit sync, from the built-in FLL/PLL's frequency and rate); the loop owns its parameters
and state and returns, after each epoch, the Doppler of the next epoch and a phase step (cycles).
"""
from __future__ import annotations

from numba import njit

from ...config import P
from .base import CarrierLoop
from .common import NWPR, PythonLoop, atan_variance_cycles2
from .runner import START_SIG, UPDATE_SIG

__all__ = ["CarrierLoop", "NWPR", "P", "PythonLoop", "START_SIG", "UPDATE_SIG", "atan_variance_cycles2",
           "nco_command", "njit"]


@njit(cache=True, nogil=True)
def nco_command(ls, i, T, start_phase, freq):
    """The NCO model in ``ls[i]`` (phase at the start of the next epoch, cycles) and ``ls[i + 1]`` (its
    frequency, Hz): set the next epoch's NCO to (start_phase, freq); returns (freq, phase step), what
    ``update`` returns (PythonLoop._command compiled)."""
    end = ls[i] + ls[i + 1] * T
    ls[i] = start_phase
    ls[i + 1] = freq
    return freq, start_phase - end
