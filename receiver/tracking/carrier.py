"""Carrier-loop interface and registry.

A carrier loop turns each epoch's prompt correlator outputs into the carrier NCO frequency for the next
epoch.  The default ``pll`` (FLL-assisted PLL, 2nd/3rd order) runs inside the numba kernel
(``builtin = True``); any other variant is a Python object stepped once per epoch by the channel:

    loop.start(doppler_hz, channel_config)
    doppler_hz = loop.update(epoch)    # epoch: one row of receiver.record.EPOCH_DTYPE (+ halves)

Adding a variant = one module with a :class:`CarrierLoop` subclass + one line in :data:`REGISTRY`.
"""
from __future__ import annotations

from ..errors import UserError


class CarrierLoop:
    """Base class. Subclasses set ``name`` and implement start/update (unless builtin)."""
    name = "base"
    builtin = False

    def __init__(self, cfg):
        self.cfg = cfg            # the tracking config Section

    def start(self, doppler_hz: float, T: float, rate_hz_s: float = 0.0, carrier_hz: float | None = None):
        self.doppler_hz = doppler_hz
        self.T = T

    def update(self, epoch) -> float:   # pragma: no cover - interface
        raise NotImplementedError


class BuiltinPLL(CarrierLoop):
    """FLL-assisted PLL (order tracking.pll_order, bandwidth tracking.pll_bw_hz) in the numba kernel."""
    name = "pll"
    builtin = True


from .loops.cpll import CPLL  # noqa: E402
from .loops.ekf import EKF, PLIEKF  # noqa: E402
from .loops.kfpll import KFPLL, AdaptiveKFPLL  # noqa: E402

REGISTRY: dict[str, type[CarrierLoop]] = {
    "pll": BuiltinPLL,
    "cpll_atan": CPLL,
    "ekf": EKF,
    "pli_ekf": PLIEKF,
    "kf": KFPLL,
    "adaptive_kf": AdaptiveKFPLL,
}


def make_carrier_loop(name: str, cfg) -> CarrierLoop:
    try:
        cls = REGISTRY[name]
    except KeyError:
        raise UserError(f"unknown carrier loop variant '{name}' (available: {', '.join(REGISTRY)})") \
            from None
    return cls(cfg)
