"""Carrier-loop interface and registry.

A carrier loop turns each epoch's prompt correlator outputs into the carrier NCO frequency for the next
epoch.  The default ``pll`` (FLL-assisted PLL, 2nd/3rd order) runs inside the numba kernel
(``builtin = True``); any other variant is a Python object (the reference) with a compiled twin in
``loops/compiled.py`` that the channel runs inside its compiled epoch loop; a variant without a twin is
stepped once per epoch from Python:

    loop.start(doppler_hz, channel_config)
    doppler_hz = loop.update(epoch)    # epoch: one row of receiver.runfile.record.EPOCH_DTYPE (+ halves)

Adding a variant = one module in ``loops/`` with a :class:`~receiver.tracking.loops.base.CarrierLoop` subclass +
one line in :data:`REGISTRY` + its compiled twin in ``loops/compiled.py`` (tests/unit/tracking/test_carrier_compiled.py
checks every variant has one).  The loop modules import only ``loops/base.py`` (and ``loops/common.py``),
never this registry.
"""
from __future__ import annotations

from ..errors import UserError
from .loops.base import CarrierLoop
from .loops.compiled import CompiledTwin
from .loops.cpll import CPLL
from .loops.ekf import EKF, PLIEKF
from .loops.kfpll import KFPLL, AdaptiveKFPLL


def _with_twin(cls):
    """The Python reference loop ``cls`` with its compiled path (loops/compiled.py)."""
    return type(cls.__name__, (CompiledTwin, cls), {"__module__": cls.__module__, "__doc__": cls.__doc__})


class BuiltinPLL(CarrierLoop):
    """FLL-assisted PLL (order tracking.pll_order, bandwidth tracking.pll_bw_hz) in the numba kernel."""
    name = "pll"
    builtin = True


REGISTRY: dict[str, type[CarrierLoop]] = {
    "pll": BuiltinPLL,
    "cpll_atan": _with_twin(CPLL),
    "ekf": _with_twin(EKF),
    "pli_ekf": _with_twin(PLIEKF),
    "kf": _with_twin(KFPLL),
    "adaptive_kf": _with_twin(AdaptiveKFPLL),
}


def channel_variant(car, weak: bool) -> str:
    """The carrier-loop variant of one channel: tracking.carrier.variant, or with ``auto`` auto_weak for a
    channel the acquisition estimated weak and auto_strong otherwise."""
    name = car["variant"]
    if name != "auto":
        return name
    return car["auto_weak"] if weak else car["auto_strong"]


def make_carrier_loop(name: str, cfg) -> CarrierLoop:
    try:
        cls = REGISTRY[name]
    except KeyError:
        raise UserError(f"unknown carrier loop variant '{name}' (available: {', '.join(REGISTRY)})") \
            from None
    return cls(cfg)
