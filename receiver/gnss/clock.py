"""Receiver oscillator classes: the power-law coefficients of the fractional-frequency noise, in one table.

One-sided PSD of the fractional frequency y:  S_y(f) = h0 + h_1 / f + h_2 / f^2  (white, flicker and
random-walk frequency modulation).  ``h_1`` / ``h_2`` stand for h_-1 / h_-2.  Values are the typical ones
quoted in GNSS textbooks for each class.  The simulator uses all three (:mod:`receiver.sim.clock`); the
two-state clock models of the Kalman filters use h0 and h_-2 (:func:`h0_h2`).
"""
from __future__ import annotations

#: class -> (h0, h_-1, h_-2)
OSCILLATORS: dict[str, tuple[float, float, float]] = {
    "tcxo": (2e-19, 7e-21, 2e-20),
    "ocxo": (8e-20, 2e-21, 4e-23),
    "rubidium": (2e-20, 7e-24, 4e-29),
}


def h0_h2(clock_class: str) -> tuple[float, float]:
    """(h0, h_-2) of an oscillator class (the two-state clock model's white-frequency and random-walk terms)."""
    h0, _, h2 = OSCILLATORS[clock_class]
    return h0, h2
