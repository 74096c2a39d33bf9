"""KML and GPX tracks of a run's fixes.

Both carry one point per fix with a finite position, in time order.  Heights are WGS-84 ellipsoidal
heights (gnssrx has no geoid model): the KML line is clamped to the ground for display, and the GPX ``ele``
element holds the ellipsoidal height (said so in the file's description).

* KML 2.2: a LineString placemark with the whole track, then a folder with one point placemark per fix
  (time stamp, navigation mode, satellites, DOPs); scalar and vector fixes have different styles.
* GPX 1.1: one track with one segment; ``trkpt`` with ``ele``, ``time`` (UTC), ``fix`` (3d), ``sat``,
  ``hdop``, ``vdop``, ``pdop``.
"""
from __future__ import annotations

from xml.sax.saxutils import escape

import numpy as np

from .. import __version__
from ..runfile.reader import RunData
from ..runfile.record import MODE_NAMES


def _points(run: RunData):
    fx = run.fixes
    if not len(fx):
        return fx
    ok = np.all(np.isfinite(fx["ecef"]), axis=1) & np.isfinite(fx["lat_deg"]) & np.isfinite(fx["lon_deg"])
    fx = fx[ok]
    return fx[np.argsort(fx["time_s"], kind="stable")]


def _iso(run: RunData, week, tow) -> str:
    t = run.utc(int(week), round(float(tow) * 1000.0) / 1000.0)
    return t.strftime("%Y-%m-%dT%H:%M:%S.") + f"{t.microsecond // 1000:03d}Z"


def kml_text(run: RunData) -> str:
    """KML 2.2 document of the run's fixes: the track line and one point placemark per fix (ellipsoidal heights)."""
    pts = _points(run)
    name = escape(run.name)
    out = ['<?xml version="1.0" encoding="UTF-8"?>',
           '<kml xmlns="http://www.opengis.net/kml/2.2">',
           "<Document>",
           f"<name>{name}</name>",
           f"<description>gnssrx {escape(__version__)} run {escape(run.name)}: {len(pts)} fixes "
           "(heights: WGS-84 ellipsoidal)</description>",
           '<Style id="track"><LineStyle><color>ff0000ff</color><width>2</width></LineStyle></Style>']
    for mode, color in ((0, "ff00ffff"), (1, "ffff00ff"), (2, "ff808080"), (3, "ff00a5ff")):
        out.append(f'<Style id="{MODE_NAMES[mode]}"><IconStyle><color>{color}</color><scale>0.4</scale>'
                   "<Icon><href>http://maps.google.com/mapfiles/kml/shapes/placemark_circle.png</href></Icon>"
                   "</IconStyle><LabelStyle><scale>0</scale></LabelStyle></Style>")
    coords = " ".join(f"{p['lon_deg']:.9f},{p['lat_deg']:.9f},{p['height_m']:.3f}" for p in pts)
    out += ["<Placemark>", "<name>track</name>", "<styleUrl>#track</styleUrl>",
            "<LineString><tessellate>1</tessellate><altitudeMode>clampToGround</altitudeMode>",
            f"<coordinates>{coords}</coordinates>", "</LineString>", "</Placemark>",
            "<Folder>", "<name>fixes</name>"]
    for i, p in enumerate(pts):
        mode = MODE_NAMES.get(int(p["mode"]), "scalar")
        out.append(
            f"<Placemark><name>{i}</name><TimeStamp><when>{_iso(run, p['gps_week'], p['gps_tow'])}</when>"
            f"</TimeStamp><styleUrl>#{mode}</styleUrl>"
            f"<description>GPS week {int(p['gps_week'])} TOW {p['gps_tow']:.3f}; {mode}; {int(p['n_sats'])} sats; "
            f"HDOP {p['hdop']:.2f} VDOP {p['vdop']:.2f}; h {p['height_m']:.2f} m</description>"
            f"<Point><altitudeMode>clampToGround</altitudeMode><coordinates>{p['lon_deg']:.9f},"
            f"{p['lat_deg']:.9f},{p['height_m']:.3f}</coordinates></Point></Placemark>")
    out += ["</Folder>", "</Document>", "</kml>"]
    return "\n".join(out) + "\n"


def _f(v, fmt):
    return format(float(v), fmt) if np.isfinite(v) else None


def gpx_text(run: RunData) -> str:
    """GPX 1.1 document of the run's fixes: one track segment, ``ele`` the ellipsoidal height, times in UTC."""
    pts = _points(run)
    out = ['<?xml version="1.0" encoding="UTF-8"?>',
           f'<gpx version="1.1" creator="gnssrx {escape(__version__)}" '
           'xmlns="http://www.topografix.com/GPX/1/1" '
           'xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance" '
           'xsi:schemaLocation="http://www.topografix.com/GPX/1/1 http://www.topografix.com/GPX/1/1/gpx.xsd">',
           "<metadata>",
           f"<name>{escape(run.name)}</name>",
           f"<desc>gnssrx run {escape(run.name)}: {len(pts)} fixes; ele = WGS-84 ellipsoidal height</desc>"]
    if len(pts):
        out.append(f"<time>{_iso(run, pts[0]['gps_week'], pts[0]['gps_tow'])}</time>")
    out += ["</metadata>", "<trk>", f"<name>{escape(run.name)}</name>", "<src>gnssrx</src>", "<trkseg>"]
    for p in pts:
        parts = [f'<trkpt lat="{p["lat_deg"]:.9f}" lon="{p["lon_deg"]:.9f}">',
                 f"<ele>{p['height_m']:.3f}</ele>",
                 f"<time>{_iso(run, p['gps_week'], p['gps_tow'])}</time>",
                 f"<type>{MODE_NAMES.get(int(p['mode']), 'scalar')}</type>",
                 "<fix>3d</fix>", f"<sat>{int(p['n_sats'])}</sat>"]
        for tag in ("hdop", "vdop", "pdop"):
            v = _f(p[tag], ".2f")
            if v is not None:
                parts.append(f"<{tag}>{v}</{tag}>")
        parts.append("</trkpt>")
        out.append("".join(parts))
    out += ["</trkseg>", "</trk>", "</gpx>"]
    return "\n".join(out) + "\n"


def write_kml(path, run: RunData) -> dict:
    """Write the KML track to `path`; returns {"points": number of fixes written}."""
    text = kml_text(run)
    with open(path, "w", encoding="utf-8") as fh:
        fh.write(text)
    return {"points": len(_points(run))}


def write_gpx(path, run: RunData) -> dict:
    """Write the GPX track to `path`; returns {"points": number of fixes written}."""
    text = gpx_text(run)
    with open(path, "w", encoding="utf-8") as fh:
        fh.write(text)
    return {"points": len(_points(run))}
