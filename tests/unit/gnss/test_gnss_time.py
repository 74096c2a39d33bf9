"""receiver.gnss.time: week wrapping and rollover, GPS epoch conversions, leap seconds."""
import datetime as dt

import numpy as np
import pytest

from receiver.gnss.time import (WEEK_S, calendar_from_gps_time, gps_datetime, gps_time_from_calendar,
                                leap_seconds_at, normalize_week_tow, split_gps_time, week_seconds_since,
                                wrap_week_seconds)


def test_wrap_week_seconds_across_the_boundary():
    # a satellite transmits at tow 604799.9 and the receiver reads 0.1 s of the next week
    assert float(wrap_week_seconds(0.1 - 604799.9)) == pytest.approx(0.2)
    assert float(wrap_week_seconds(604799.9 - 0.1)) == pytest.approx(-0.2)
    assert np.allclose(wrap_week_seconds([-302400.0, 302399.0]), [-302400.0, 302399.0])


def test_normalize_week_tow_moves_the_week():
    assert normalize_week_tow(2190, -0.5) == (2189, WEEK_S - 0.5)
    assert normalize_week_tow(2190, WEEK_S + 0.25) == (2191, 0.25)
    assert normalize_week_tow(2190, 1234.5) == (2190, 1234.5)


def test_week_seconds_since():
    assert week_seconds_since(2191, 10.0, 2190) == WEEK_S + 10.0
    np.testing.assert_array_equal(week_seconds_since(np.array([2190, 2191]), np.array([5.0, 5.0]), 2190),
                                  [5.0, WEEK_S + 5.0])


def test_calendar_round_trip_and_datetime():
    week, sow = gps_time_from_calendar(2022, 1, 1, 0, 0, 0.0)
    assert (week, sow) == (2190, 518400.0)                     # Saturday 2022-01-01 00:00 GPS time
    assert calendar_from_gps_time(week, sow) == dt.datetime(2022, 1, 1)
    assert gps_datetime(2190, 518400.000001) == dt.datetime(2022, 1, 1, 0, 0, 0, 1)
    t, frac = split_gps_time(2190, 518400.99999999, 7)
    assert t == dt.datetime(2022, 1, 1, 0, 0, 1) and frac == 0.0


def test_leap_seconds_table():
    assert leap_seconds_at(dt.datetime(2022, 1, 1)) == 18
    assert leap_seconds_at(dt.datetime(2016, 12, 31)) == 17
    assert leap_seconds_at(dt.datetime(1980, 1, 6)) == 0
