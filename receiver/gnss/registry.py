"""Signal registry: configured ``signal`` name -> :class:`~receiver.gnss.signals.SignalDef`.

The signal modules define their ``SignalDef``; this module, above them, lists them (``signals_bds`` imports
``signals``, never the reverse).
"""
from __future__ import annotations

from .signals import GPS_L1CA, SignalDef
from .signals_bds import BDS_B1I
from .signals_gal import GAL_E1
from .signals_gal_e5a import GAL_E5A
from .signals_l5 import GPS_L5

SIGNALS: dict[str, SignalDef] = {"gps_l1ca": GPS_L1CA, "bds_b1i": BDS_B1I, "gal_e1": GAL_E1,
                               "gps_l5": GPS_L5, "gal_e5a": GAL_E5A}
SIGNAL_NAMES = tuple(SIGNALS)


def get_signal(name: str) -> SignalDef:
    """The SignalDef of a configured ``signal`` name."""
    try:
        return SIGNALS[name]
    except KeyError:
        raise ValueError(f"unknown signal '{name}' (one of {', '.join(SIGNAL_NAMES)})") from None
