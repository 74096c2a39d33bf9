"""Candidate transmit times for the assisted first fix (receiver.navigation.engine ``_resolve_assisted``).

In assisted mode a bit-synchronised channel knows its transmit time modulo its bit period (20 ms for GPS
LNAV and BeiDou D1) but not which bit it is in; the first fix tries sets of guesses and keeps the one
whose fix uses the most satellites, then fits best.  Two kinds of guesses:

* one common travel time of 60-95 ms for every MEO satellite (and a second of 115-140 ms for BeiDou GEO /
  IGSO satellites): right for every satellite only when their travel times lie within +/-10 ms of it, i.e.
  span at most 20 ms.  GPS alone spans 67-86 ms down to the horizon, but GPS with BeiDou MEO satellites
  spans up to 67-89 ms (a GPS satellite at the zenith, a BeiDou one below ~8 deg);
* the travel time of each satellite from a rough receiver position -- the direction of the mean of the
  satellites' unit vectors, on the Earth's surface (the satellites a receiver tracks lie around its
  zenith) -- plus a common offset of -15..+15 ms: right while that position is within ~2800 km of the
  receiver (its error moves the satellites' travel times apart by at most 2 |error| / c).

The common travel times are tried first; a predicted guess replaces their best fix only with one that uses more
satellites or, with as many, fits better.
"""
from __future__ import annotations

import numpy as np

from ..gnss.ephemeris import sat_state
from ..gnss.signals import C_LIGHT

EARTH_RADIUS_M = 6371e3
COMMON_S = np.arange(0.060, 0.0955, 0.001)       # common MEO travel times
DEEP_S = np.arange(0.115, 0.1405, 0.001)         # common GEO / IGSO travel times
OFFSET_S = np.arange(-0.015, 0.0155, 0.001)      # common offsets around the predicted travel times


def centroid_position(sat_ecef: np.ndarray) -> np.ndarray:
    """A rough receiver position (ECEF, m): the mean direction of the satellites seen from the Earth's centre,
    on a sphere of the Earth's mean radius."""
    u = sat_ecef / np.linalg.norm(sat_ecef, axis=1)[:, None]
    m = u.mean(axis=0)
    return EARTH_RADIUS_M * m / np.linalg.norm(m)


def common_guesses(prns, T: float, deep: set):
    """Yield {prn: transmit-time guess} for every common travel time (a pair of them, MEO and GEO / IGSO,
    when ``deep``, the PRNs of GEO / IGSO satellites, is not empty) at receiver time ``T``."""
    for c in COMMON_S:
        for c2 in (DEEP_S if deep else (c,)):
            yield {p: T - (c2 if p in deep else c) for p in prns}


def predicted_guesses(prns, sat_ecef: np.ndarray, T: float):
    """Yield {prn: transmit-time guess}: the travel times from :func:`centroid_position` of the satellites at
    ``sat_ecef`` (row per PRN) plus each common offset of OFFSET_S."""
    tau = np.linalg.norm(sat_ecef - centroid_position(sat_ecef), axis=1) / C_LIGHT
    for d in OFFSET_S:
        yield {p: T - (t + d) for p, t in zip(prns, tau)}


def guesses(cand, T: float, deep: set):
    """Yield the candidate transmit times {prn: GPS seconds of week} of the channels ``cand`` ((channel,
    ephemeris, relative transmit time) triples) at receiver time ``T``: :func:`common_guesses`, then (from 4
    satellites on) :func:`predicted_guesses` from the satellites' positions 75 ms before ``T``."""
    prns = [ch.prn for ch, _, _ in cand]
    yield from common_guesses(prns, T, deep)
    if len(cand) >= 4:
        pos = np.array([np.asarray(sat_state(e, T - 0.075)[0], float) for _, e, _ in cand])
        yield from predicted_guesses(prns, pos, T)


class Retries:
    """When the first-fix search runs: at every navigation epoch for the first ``eager_s`` seconds after its
    first failure, then once every ``every_s`` seconds.  A search that keeps
    failing (a start time more than 10 ms off, an ephemeris file of another day) then costs a tenth of what it
    did at 10 Hz: with BeiDou GEO / IGSO satellites one search solves ~960 candidate fixes."""

    def __init__(self, eager_s: float = 5.0, every_s: float = 1.0):
        self.eager_s, self.every_s = eager_s, every_s
        self.first_failure = None
        self.next_t = None

    def due(self, t: float) -> bool:
        """Whether to search at receiver time ``t`` (s)."""
        return self.next_t is None or t >= self.next_t

    def done(self, t: float, found: bool) -> None:
        """Record the search at ``t``: the next is due at once while it finds an assignment or within
        ``eager_s`` of its first failure, else ``every_s`` later."""
        if found:
            self.first_failure = self.next_t = None
            return
        if self.first_failure is None:
            self.first_failure = t
        self.next_t = None if t - self.first_failure < self.eager_s else t + self.every_s
