"""GPS time: the week, week-second wrapping and rollover, the GPS epoch and leap seconds -- in one place.

GPS time is kept as (full week number, seconds of week).  Time *differences* across a week boundary are
wrapped into +/- half a week (:func:`wrap_week_seconds`); a time of week that left [0, 604800) after an
addition is brought back by moving the week (:func:`normalize_week_tow`).
"""
from __future__ import annotations

import datetime as _dt
import math

import numpy as np

WEEK_S = 604800.0
HALF_WEEK = 302400.0
GPS_EPOCH = _dt.datetime(1980, 1, 6)

# GPS - UTC (s) in force from each UTC date on (the leap seconds inserted since the GPS epoch)
_LEAP_TABLE = (
    (_dt.datetime(1981, 7, 1), 1), (_dt.datetime(1982, 7, 1), 2), (_dt.datetime(1983, 7, 1), 3),
    (_dt.datetime(1985, 7, 1), 4), (_dt.datetime(1988, 1, 1), 5), (_dt.datetime(1990, 1, 1), 6),
    (_dt.datetime(1991, 1, 1), 7), (_dt.datetime(1992, 7, 1), 8), (_dt.datetime(1993, 7, 1), 9),
    (_dt.datetime(1994, 7, 1), 10), (_dt.datetime(1996, 1, 1), 11), (_dt.datetime(1997, 7, 1), 12),
    (_dt.datetime(1999, 1, 1), 13), (_dt.datetime(2006, 1, 1), 14), (_dt.datetime(2009, 1, 1), 15),
    (_dt.datetime(2012, 7, 1), 16), (_dt.datetime(2015, 7, 1), 17), (_dt.datetime(2017, 1, 1), 18),
)


def wrap_week_seconds(dt):
    """Wrap a time difference (s) into [-302400, 302400) (week crossover)."""
    return (np.asarray(dt, dtype=float) + HALF_WEEK) % WEEK_S - HALF_WEEK


def normalize_week_tow(week: int, tow: float) -> tuple[int, float]:
    """(week, tow) with a time of week that left [0, 604800) by less than a week brought back into it."""
    if tow < 0:
        return week - 1, tow + WEEK_S
    if tow >= WEEK_S:
        return week + 1, tow - WEEK_S
    return week, tow


def week_seconds_since(week, tow, ref_week):
    """Seconds since the start of ``ref_week`` (arrays or scalars): (week - ref_week) * 604800 + tow."""
    return (week - ref_week) * WEEK_S + tow


def leap_seconds_at(gps_time: _dt.datetime) -> int:
    """GPS - UTC (s) from the built-in table (used when the message's value is not known)."""
    n = 0
    for since, value in _LEAP_TABLE:
        if gps_time >= since + _dt.timedelta(seconds=value):
            n = value
    return n


def gps_datetime(week: int, tow: float) -> _dt.datetime:
    """GPS week + seconds of week -> naive datetime on the GPS time scale (microsecond resolution)."""
    whole = math.floor(tow)
    return (GPS_EPOCH + _dt.timedelta(days=7 * int(week), seconds=int(whole))
            + _dt.timedelta(microseconds=round((tow - whole) * 1e6)))


def split_gps_time(week: int, tow: float, decimals: int):
    """GPS week + seconds of week -> (datetime to the whole second, fractional seconds rounded to
    ``decimals``) without losing precision (a datetime keeps only microseconds)."""
    whole = math.floor(tow)
    scale = 10 ** decimals
    frac = round((tow - whole) * scale)
    if frac >= scale:
        whole, frac = whole + 1, frac - scale
    t = GPS_EPOCH + _dt.timedelta(days=7 * int(week), seconds=int(whole))
    return t, frac / scale


def gps_time_from_calendar(y, mo, d, h, mi, s):
    """Calendar date/time (GPS time scale) -> (full GPS week, seconds of week)."""
    whole = int(math.floor(s))
    t = _dt.datetime(y, mo, d, h, mi, whole)
    sec = (t - GPS_EPOCH).total_seconds() + (s - whole)
    week = int(sec // WEEK_S)
    return week, sec - week * WEEK_S


def calendar_from_gps_time(week, sow):
    """(full GPS week, seconds of week) -> datetime (GPS time scale)."""
    return GPS_EPOCH + _dt.timedelta(seconds=week * WEEK_S + sow)
