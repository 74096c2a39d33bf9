"""KML and GPX tracks (receiver.export.tracks) of the reference run."""
import datetime as dt
import xml.etree.ElementTree as ET

import numpy as np

from receiver.runfile.reader import load_run

KML = "{http://www.opengis.net/kml/2.2}"
GPX = "{http://www.topografix.com/GPX/1/1}"


def test_kml_is_valid_xml_with_one_point_per_fix(tokyo_exports):
    run = load_run(tokyo_exports["h5"])
    fx = run.fixes
    root = ET.parse(tokyo_exports["kml"]).getroot()
    assert root.tag == KML + "kml"
    line = root.find(f".//{KML}LineString/{KML}coordinates").text.split()
    assert len(line) == len(fx) > 300
    lon, lat, h = np.array([[float(v) for v in c.split(",")] for c in line]).T
    assert np.max(np.abs(lat - fx["lat_deg"])) < 1e-8 and np.max(np.abs(lon - fx["lon_deg"])) < 1e-8
    assert np.allclose(h, fx["height_m"], atol=1e-3)
    points = root.findall(f".//{KML}Folder/{KML}Placemark")
    assert len(points) == len(fx)
    when = [p.find(f"{KML}TimeStamp/{KML}when").text for p in points]
    t = [dt.datetime.strptime(w, "%Y-%m-%dT%H:%M:%S.%fZ") for w in when]
    assert all(b > a for a, b in zip(t, t[1:]))
    assert t[0].date() == dt.date(2022, 1, 1)
    assert {p.find(f"{KML}styleUrl").text for p in points} == {"#scalar"}
    # every point within 20 m of the truth (Tokyo, 35.681298 N 139.766247 E)
    north = np.radians(lat - 35.681298) * 6.371e6
    east = np.radians(lon - 139.766247) * 6.371e6 * np.cos(np.radians(35.68))
    assert np.max(np.hypot(east, north)) < 20.0


def test_gpx_is_valid_gpx11_with_one_trackpoint_per_fix(tokyo_exports):
    run = load_run(tokyo_exports["h5"])
    fx = run.fixes
    root = ET.parse(tokyo_exports["gpx"]).getroot()
    assert root.tag == GPX + "gpx" and root.get("version") == "1.1"
    segs = root.findall(f"{GPX}trk/{GPX}trkseg")
    assert len(segs) == 1
    pts = segs[0].findall(f"{GPX}trkpt")
    assert len(pts) == len(fx) > 300
    lat = np.array([float(p.get("lat")) for p in pts])
    lon = np.array([float(p.get("lon")) for p in pts])
    assert np.max(np.abs(lat - fx["lat_deg"])) < 1e-8 and np.max(np.abs(lon - fx["lon_deg"])) < 1e-8
    ele = np.array([float(p.find(f"{GPX}ele").text) for p in pts])
    assert np.allclose(ele, fx["height_m"], atol=1e-3)
    assert [int(p.find(f"{GPX}sat").text) for p in pts] == fx["n_sats"].tolist()
    # schema order of the waypoint children (ele, time, ..., type, fix, sat, hdop, vdop, pdop)
    order = ["ele", "time", "type", "fix", "sat", "hdop", "vdop", "pdop"]
    assert [c.tag[len(GPX):] for c in pts[0]] == order
    times = [dt.datetime.strptime(p.find(f"{GPX}time").text, "%Y-%m-%dT%H:%M:%S.%fZ") for p in pts]
    gps0 = dt.datetime(1980, 1, 6) + dt.timedelta(weeks=int(fx["gps_week"][0]), seconds=float(fx["gps_tow"][0]))
    assert abs((gps0 - dt.timedelta(seconds=18) - times[0]).total_seconds()) < 0.001
    assert np.allclose(np.diff([(t - times[0]).total_seconds() for t in times]), 0.1, atol=0.0011)
