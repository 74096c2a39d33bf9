"""Where the navigation engine's satellites get their ephemerides and the ionosphere its parameters
(:class:`EphemerisStore`, a part of :class:`receiver.navigation.engine.NavigationEngine`): the broadcast
file's records in assisted mode, else what each channel's decoder has decoded; the Klobuchar set from the
file header, a decoder, or the fallback set; the GPS week."""
from __future__ import annotations

from ..gnss.signals import L1_HZ
from ..runfile.record import IONO_BROADCAST, IONO_FALLBACK, IONO_NONE


class EphemerisStore:
    """The navigation interface for the trackers (vector loop, channel manager) that concerns ephemerides and
    the ionosphere.  Mixed into the engine, whose state it reads: ``assisted``, ``rinex_ephs`` (prn -> list of
    Ephemeris of the broadcast file), ``channels`` (prn -> ChannelNav with its decoder), ``iono_utc``,
    ``iono_fallback``, ``signals`` and ``solver``."""

    def ephemerides(self, t):
        """prn -> Ephemeris valid at GPS time t: the RINEX file's (assisted mode) or the decoded ones, for
        every satellite met during the run (tracked now or not)."""
        from ..gnss.ephemeris import select
        out = {}
        if self.assisted:
            for prn, lst in self.rinex_ephs.items():
                e = select(lst, t)
                if e is not None:
                    out[prn] = e
            return out
        for prn, ch in self.channels.items():
            if ch.decoder.ephemeris is not None:
                out[prn] = ch.decoder.ephemeris
        return out

    def ephemeris(self, prn: int, t):
        """ephemerides(t).get(prn), selecting for prn only."""
        if self.assisted:
            from ..gnss.ephemeris import select
            return select(self.rinex_ephs.get(prn), t)
        ch = self.channels.get(prn)
        return ch.decoder.ephemeris if ch is not None else None

    def _ephemerides(self, t):
        """The ephemerides of the satellites with navigation memory (the fixes' candidates)."""
        from ..gnss.ephemeris import select
        out = {}
        for prn, ch in self.channels.items():
            if self.assisted and prn in self.rinex_ephs:
                e = select(self.rinex_ephs[prn], t)
                if e is not None:
                    out[prn] = e
            elif ch.decoder.ephemeris is not None:
                out[prn] = ch.decoder.ephemeris
        return out

    def decoded_ephemerides(self) -> dict:
        """prn -> the latest ephemeris decoded from the signal during the run (every satellite)."""
        return {p: ch.decoder.ephemeris for p, ch in sorted(self.channels.items())
                if ch.decoder.ephemeris is not None}

    def broadcast_iono(self):
        """The broadcast Klobuchar / GPS-UTC set: the RINEX header's (assisted mode; not when the header has
        GPS-UTC terms but no ION ALPHA / BETA: the reader leaves alpha and beta zero), else the first decoded
        by any channel; None while none is known.

        A run over several signals with GPS among them applies one GPS set to every satellite (scaled to each
        carrier, receiver.navigation.pvt): a BeiDou D1/D2 set (reference carrier B1I) counts only while no GPS
        set is known and no fallback set is configured.  The solver evaluates every set with the GPS
        (IS-GPS-200) Klobuchar formula, for which the BeiDou coefficients are not made; with the GPS set for
        all, the GPS satellites of a combined fix get the same correction as in a GPS-only fix."""
        if self.iono_utc is not None and (any(self.iono_utc.alpha) or any(self.iono_utc.beta)):
            return self.iono_utc
        # (several signals: GPS keys first, so the GPS set wins over BeiDou's once both are decoded)
        gps_first = bool(self.signals) and "G" in self.signals and self.iono_fallback is not None
        for ch in (self.channels.values() if not self.signals else
                   (c for _, c in sorted(self.channels.items()))):
            io = ch.decoder.iono_utc
            if io is not None and not (gps_first and float(getattr(io, "ref_hz", L1_HZ)) != L1_HZ):
                return io
        return None

    def iono(self):
        """The Klobuchar set the fixes use now: the broadcast one, else the fallback set
        (navigation.klobuchar_fallback), else None (no ionospheric correction)."""
        io = self.broadcast_iono()
        return io if io is not None else self.iono_fallback

    def iono_params(self) -> int:
        """FIX_DTYPE iono_params of a fix computed now: IONO_BROADCAST, IONO_FALLBACK or IONO_NONE (no
        parameters, or navigation.ionosphere none)."""
        if self.solver.ionosphere != "klobuchar":
            return IONO_NONE
        if self.broadcast_iono() is not None:
            return IONO_BROADCAST
        return IONO_FALLBACK if self.iono_fallback is not None else IONO_NONE

    def week(self):
        """GPS week (decoded, else input.start_gps_week), or None."""
        for ch in self.channels.values():
            if ch.decoder.week is not None:
                return ch.decoder.week
        return self.week_hint

    _week = week
