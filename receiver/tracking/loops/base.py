"""The carrier-loop interface (see :mod:`receiver.tracking.carrier` for the registry of variants and
receiver/tracking/loops/plugin.py / docs/plugins.md for writing one outside the package)."""
from __future__ import annotations


class CarrierLoop:
    """Base class of every carrier loop, built-in or plugin.

    ``name``: the variant name (``tracking.carrier.variant``); ``version``: reported with a plugin (None:
    its distribution's version); ``PARAMS``: the loop's own config keys, a schema fragment of
    :class:`receiver.config.P` mounted at ``tracking.carrier.<name>`` and given to the loop as
    ``self.params`` (the built-ins' keys are the historical ones of receiver/tracking/config.py).
    ``builtin``: only the kernel's own FLL-assisted PLL (no methods).

    Reference path: :meth:`start` when the loop takes the carrier over (at bit sync), then
    :meth:`update` after every epoch, returning (Doppler of the next epoch Hz, NCO phase step cycles).
    Compiled path (optional): :meth:`compiled` returns ``(start, update, lp, ls)``, two numba functions of
    the signatures START_SIG / UPDATE_SIG (receiver/tracking/loops/runner.py) and the float64 parameter and
    state arrays they work on; the channel then runs them inside its compiled epoch loop.
    """
    name = "base"
    version: str | None = None
    builtin = False
    PARAMS: dict = {}

    def __init__(self, cfg):
        self.cfg = cfg            # the tracking config Section
        self.params = cfg.carrier[self.name] if (self.PARAMS and cfg is not None) else None

    def start(self, doppler_hz: float, T: float, rate_hz_s: float = 0.0, carrier_hz: float | None = None):
        """(Re)start the loop at doppler_hz (Hz) with epoch length T (s); rate_hz_s is the Doppler rate
        (Hz/s), carrier_hz the carrier frequency (Hz; None: kept)."""
        self.doppler_hz = doppler_hz
        self.T = T

    def update(self, epoch) -> float:   # pragma: no cover - interface
        """One epoch from a kernel output row (a variant implements it; the built-in loops return the
        Doppler for the next epoch, Hz, and the phase step, cycles)."""
        raise NotImplementedError

    def compiled(self):
        """``(start, update, lp, ls)`` of the compiled path, or None (stepped from Python)."""
        return None
