"""Carrier-loop interface and registry.

A carrier loop turns each epoch's prompt correlator outputs into the carrier NCO frequency for the next
epoch.  The default ``pll`` (FLL-assisted PLL, 2nd/3rd order) runs inside the numba kernel
(``builtin = True``); any other variant is a Python object (the reference) with a compiled twin in
``loops/compiled.py`` that the channel runs inside its compiled epoch loop; a variant without a twin is
stepped once per epoch from Python:

    loop.start(doppler_hz, channel_config)
    doppler_hz = loop.update(epoch)    # epoch: one row of receiver.runfile.record.EPOCH_DTYPE (+ halves)

Adding a built-in variant = one module in ``loops/`` with a :class:`~receiver.tracking.loops.base.CarrierLoop`
subclass + one line in :data:`REGISTRY` + its compiled twin in ``loops/compiled.py``
(tests/unit/tracking/test_carrier_compiled.py checks every variant has one).  A loop outside the package
implements the same interface and is found by :func:`loop_class` (entry point ``gnssrx.carrier_loops`` or
``module:Class``; docs/plugins.md).  The loop modules import only ``loops/base.py`` (and ``loops/common.py``),
never this registry.
"""
from __future__ import annotations

from .. import plugins
from ..errors import UserError
from .loops.base import CarrierLoop
from .loops.common import PythonLoop
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


def loop_class(name: str) -> type[CarrierLoop]:
    """The class of carrier-loop variant ``name``: a built-in (:data:`REGISTRY`), an installed plugin (entry
    point ``gnssrx.carrier_loops``) or ``module:Class``; checked against the interface (one-line errors)."""
    if name in REGISTRY:
        return REGISTRY[name]
    found = plugins.find("carrier_loop", name)
    if found is None:
        avail = list(REGISTRY) + sorted(plugins.entry_points("carrier_loop"))
        raise UserError(f"unknown carrier loop variant '{name}' (available: {', '.join(avail)}, or "
                        f"module:Class)")
    return check_class(found.name, found.cls)


def check_class(name: str, cls) -> type[CarrierLoop]:
    """``cls`` implements the carrier-loop interface (loops/base.py): a CarrierLoop with a name, update and
    a PARAMS fragment of config parameters."""
    pre = f"carrier loop plugin '{name}'"
    if not (isinstance(cls, type) and issubclass(cls, CarrierLoop)):
        raise UserError(f"{pre}: {getattr(cls, '__name__', cls)} is not a receiver.tracking.loops.base.CarrierLoop")
    if not isinstance(cls.name, str) or not cls.name.isidentifier() or cls.name == CarrierLoop.name:
        raise UserError(f"{pre}: its class attribute name must be an identifier (the config section of its "
                        f"parameters), got {cls.name!r}")
    if cls.builtin:
        raise UserError(f"{pre}: builtin = True is the kernel's own PLL only")
    for method in ("start", "update", "compiled"):
        if not callable(getattr(cls, method, None)):
            raise UserError(f"{pre}: missing method {method}")
    if issubclass(cls, PythonLoop):
        for method in ("init", "step"):
            if getattr(cls, method) is getattr(PythonLoop, method):
                raise UserError(f"{pre}: missing method {method} (a PythonLoop implements init and step)")
    elif cls.update is CarrierLoop.update:
        raise UserError(f"{pre}: missing method update")
    plugins.check_params(pre, cls.PARAMS)
    return cls


def make_carrier_loop(name: str, cfg, check: bool = False) -> CarrierLoop:
    """A loop of variant ``name`` for a channel (``cfg``: the tracking section).  ``check``: also compile its
    compiled path for the interface's signatures (the pipeline does it once before the run)."""
    loop = loop_class(name)(cfg)
    if check:
        try:
            twin = loop.compiled()
            if twin is not None:
                from .loops.runner import loop_functions
                loop_functions(twin)
        except UserError:
            raise
        except Exception as exc:  # noqa: BLE001 - a plugin's compiled path that does not build: one line
            msg = str(exc).strip().splitlines()
            raise UserError(f"carrier loop '{name}': its compiled path does not build for the interface "
                            f"(receiver/tracking/loops/runner.py START_SIG / UPDATE_SIG): "
                            f"{type(exc).__name__}: {msg[0] if msg else ''}") from None
    return loop
