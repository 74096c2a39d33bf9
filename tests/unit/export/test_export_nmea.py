"""NMEA export (receiver.export.nmea) of the reference run: checksums, pynmea2 parsing, content."""
import datetime as dt

import numpy as np
import pytest

from receiver.export.nmea import _latlon, checksum, gsv, sentence
from receiver.runfile.reader import load_run


def _xor(body):
    c = 0
    for ch in body:
        c ^= ord(ch)
    return c


def test_sentence_checksum_and_coordinates():
    s = sentence("GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,")
    assert s.endswith("*47")                     # the textbook example sentence
    assert checksum("") == "00"
    assert _latlon(35.5, True) == ("3530.0000000", "N")
    assert _latlon(-139.99999999999, False) == ("14000.0000000", "W")     # minutes never print as 60
    assert _latlon(0.0, False) == ("00000.0000000", "E")
    assert len(gsv([])) == 1 and gsv([])[0].startswith("$GPGSV,1,1,00*")
    six = gsv([(p, 10.0, 20.0, 40.0) for p in range(1, 7)])
    assert [s.split(",")[1:4] for s in six] == [["2", "1", "06"], ["2", "2", "06"]]


@pytest.fixture(scope="module")
def sentences(tokyo_exports):
    with open(tokyo_exports["nmea"], "rb") as fh:
        raw = fh.read()
    assert raw.endswith(b"\r\n") and b"\n" not in raw.replace(b"\r\n", b"")
    return raw.decode("ascii").split("\r\n")[:-1]


@pytest.mark.slow
def test_every_sentence_has_a_valid_checksum(sentences):
    assert len(sentences) > 1000
    for s in sentences:
        assert s[0] == "$" and s[-3] == "*"
        body, cs = s[1:-3], s[-2:]
        assert int(cs, 16) == _xor(body), s
        assert len(s) <= 82 or s.startswith(("$GPGGA", "$GPRMC")), s   # high-precision GGA/RMC may exceed 82


def test_pynmea2_parses_everything_and_content_matches_the_fixes(sentences, tokyo_exports):
    pynmea2 = pytest.importorskip("pynmea2", reason="pynmea2 not installed (pip install '.[test]')")
    msgs = [pynmea2.parse(s, check=True) for s in sentences]
    run = load_run(tokyo_exports["h5"])
    fx = run.fixes
    gga = [m for m in msgs if m.sentence_type == "GGA"]
    rmc = [m for m in msgs if m.sentence_type == "RMC"]
    gsa = [m for m in msgs if m.sentence_type == "GSA"]
    gsv_ = [m for m in msgs if m.sentence_type == "GSV"]
    assert len(gga) == len(rmc) == len(gsa) == len(fx) > 300
    assert {m.talker for m in msgs} == {"GP"}
    lat = np.array([m.latitude for m in gga])
    lon = np.array([m.longitude for m in gga])
    assert np.max(np.abs(lat - fx["lat_deg"])) < 1e-8
    assert np.max(np.abs(lon - fx["lon_deg"])) < 1e-8
    assert np.allclose([float(m.altitude) for m in gga], fx["height_m"], atol=1e-3)
    assert all(int(m.gps_qual) == 1 for m in gga)
    assert [int(m.num_sats) for m in gga] == fx["n_sats"].tolist()
    # UTC = GPS - 18 s on 2022-01-01
    gps0 = dt.datetime(1980, 1, 6) + dt.timedelta(weeks=int(fx["gps_week"][0]), seconds=float(fx["gps_tow"][0]))
    utc0 = dt.datetime.combine(rmc[0].datestamp, rmc[0].timestamp.replace(tzinfo=None))
    assert abs((gps0 - dt.timedelta(seconds=18) - utc0).total_seconds()) < 0.006
    assert rmc[0].datestamp == dt.date(2022, 1, 1) and rmc[0].status == "A"
    assert all(float(m.spd_over_grnd) < 1.0 for m in rmc)       # static antenna
    # GSA lists the satellites used in each fix; GSV the tracked ones with elevation and C/N0
    o = run.obs
    t0 = fx["time_s"][0]
    used0 = sorted(int(p) for p in o["prn"][(o["time_s"] == t0) & (o["used_in_fix"] == 1)])
    sv0 = sorted(int(getattr(gsa[0], f"sv_id{k:02d}")) for k in range(1, 13) if getattr(gsa[0], f"sv_id{k:02d}"))
    assert sv0 == used0
    assert float(gsa[0].pdop) == pytest.approx(fx["pdop"][0], abs=0.006)
    n_view = int(gsv_[0].num_sv_in_view)
    assert n_view == int(np.count_nonzero(o["time_s"] == t0))
    first = gsv_[: int(gsv_[0].num_messages)]
    sats = [(getattr(m, f"sv_prn_num_{k}"), getattr(m, f"elevation_deg_{k}"), getattr(m, f"snr_{k}"))
            for m in first for k in range(1, 5) if getattr(m, f"sv_prn_num_{k}", "")]
    assert len(sats) == n_view
    assert all(el != "" and 0 <= int(el) <= 90 and 20 <= int(snr) <= 60 for _, el, snr in sats)
