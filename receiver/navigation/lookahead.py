"""Fixed-lag smoothing of a recording's fixes (``navigation.lookahead_s``; docs: Navigation, fixed-lag smoothing).

A real-time receiver smooths an epoch's code with the epochs before it only: the first seconds of a carrier arc
carry nearly the raw code error.  :class:`FixedLag` holds each epoch's fix, observable rows and what solving it
needs (receiver time, observations, ephemerides, ionosphere, the aiding it used, and per satellite a reference to
the carrier-smoothing fit it was smoothed with) for ``lag_s``, then solves it again: each pseudorange smoothed
with its arc's fit as it stands at release time.  A fit object keeps growing while its arc lasts and is left as
it was when the arc ends (ChannelNav.smooth_update starts a new one), so an epoch never sees the code of a
later arc.  The navigation engine's own state (aiding, epoch placement, x0) stays on the causal fixes.
Memory: lag_s x rate_hz epochs.
"""
from __future__ import annotations

import logging
import math
from collections import deque

import numpy as np

from ..gnss.signals import C_LIGHT
from .channel import common_slope
from .pvt import Observation


class FixedLag:
    """The held epochs of a run (in epoch order) and their second solution."""

    def __init__(self, lag_s: float, solver, max_pdop: float, fix_row):
        self.lag_s = float(lag_s)
        self.solver = solver
        self.max_pdop = float(max_pdop)
        self.fix_row = fix_row      # (fix, fix, t_s, iono code) -> FIX_DTYPE row (the engine's layout)
        self.held = deque()         # (t_s, fix row or None, observable rows, context or None)

    @classmethod
    def for_run(cls, nav_cfg, solver, aid_cfg, pvt_filter, fix_row):
        """The run's FixedLag from navigation.lookahead_s, or None (0, or a PVT filter's fixes: causal)."""
        lag = float(getattr(nav_cfg, "lookahead_s", 0.0) or 0.0)
        if lag > 0.0 and pvt_filter is not None:
            logging.getLogger(__name__).warning("navigation.lookahead_s not used with navigation.filter %s "
                                                "(its fixes stay causal)", nav_cfg.filter)
            return None
        return cls(lag, solver, getattr(aid_cfg, "max_pdop", math.inf), fix_row) if lag > 0.0 else None

    def hold(self, t_s: float, row, obs_rows, ctx):
        """Hold epoch t_s; the held epochs now lag_s old or older, solved again: [(row, obs_rows), ...]."""
        self.held.append((t_s, row, obs_rows, ctx))
        return self.release(t_s - self.lag_s)

    def release(self, t_until: float = math.inf):
        """The held epochs up to t_until (s; all of them by default: the end of the input)."""
        out = []
        while self.held and self.held[0][0] <= t_until:
            _, row, obs_rows, ctx = self.held.popleft()
            out.append((row, obs_rows) if ctx is None else self._again(row, obs_rows, ctx))
        return out

    def _again(self, row, obs_rows, ctx):
        """An epoch's fix solved again: each pseudorange smoothed with its carrier arc's fit as it is now (the
        arc's code up to now, or to its end), the common code-minus-carrier drift from the same arcs, at the
        same receiver time, geometry and ephemerides.  An aided epoch is solved without its aiding when it has
        4 satellites or more and a PDOP within aiding.max_pdop, else with the same constraints."""
        week, rx_tow, observations, ephs, iono, fix, raw, aid = ctx
        aid = aid if fix.aiding else None          # (the aiding the epoch's fix was solved with)
        slope = common_slope([i for i in (ch.slope_info(h) for ch, _, _, _, _, h in raw.values() if h is not None)
                              if i is not None])
        new_obs = []
        for o in observations:
            ch, s, txrel_raw, phase, txrel_used, h = raw[o.prn]
            txrel = ch.smooth_value(s, txrel_raw, phase, slope, h) if h is not None else txrel_used
            new_obs.append(Observation(prn=o.prn, tx_tow=o.tx_tow + (txrel - txrel_used), doppler_hz=o.doppler_hz,
                                       cn0_dbhz=o.cn0_dbhz, carrier_phase_cycles=o.carrier_phase_cycles,
                                       wavelength_m=o.wavelength_m, system=o.system))
        fx = None
        if len(new_obs) >= 4:
            fx = self.solver.fix(week, rx_tow, new_obs, ephs, iono, x0=fix.ecef)
            if fx is not None and aid is not None and fx.pdop > self.max_pdop:
                fx = None
        if fx is None and aid is not None:
            fx = self.solver.fix(week, rx_tow, new_obs, ephs, iono, x0=fix.ecef, aid=aid)
        if fx is None:
            return row, obs_rows
        row = self.fix_row(fx, fx, row[2], row[-1])
        used = set(fx.prns)
        el = dict(zip(fx.prns, fx.elevations_deg))
        az = dict(zip(fx.prns, fx.azimuths_deg))
        res = dict(zip(fx.prns, fx.residuals_m))
        tx = {o.prn: o.tx_tow for o in new_obs}
        rows = []
        for r in obs_rows:          # (epoch, week, tow, time_s, prn, pseudorange, ..., used, el, az, residual)
            r = list(r)
            p = r[4]
            r[1], r[2] = fx.gps_week, fx.gps_tow
            r[5] = (rx_tow - tx[p]) * C_LIGHT
            r[12] = 1 if p in used else 0
            r[13], r[14], r[15] = el.get(p, np.nan), az.get(p, np.nan), res.get(p, np.nan)
            rows.append(tuple(r))
        return row, rows
