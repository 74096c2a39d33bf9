"""The carrier-loop interface (see :mod:`receiver.tracking.carrier` for the registry of variants)."""
from __future__ import annotations


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
