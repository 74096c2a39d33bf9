"""An independent GPS L1 C/A + BeiDou B1I (+ Galileo E1) recording (one file, both bands) made with SignalSim's
IFdataGen (globsky/SignalSim: an outside simulator used as a test tool, fetched and built locally, never shipped).

The script writes everything IFdataGen needs and then calls it:
  * REC.nav   RINEX 3 mixed navigation file: the GPS records of a broadcast file (default ../shared/data/
              brdc0010.22n, the record valid at the start for every PRN) and gnssrx's nominal BeiDou
              constellation (data/bds_nominal_constellation.yaml) re-epoched to the start, written by
              receiver.gnss.rinex.write_rinex_nav; the header gets the GPS Klobuchar set also as the BeiDou
              set (BDSA/BDSB) and GPS-UTC / BDT-UTC lines, which IFdataGen needs to broadcast them; with
              ``--galileo`` also gnssrx's nominal Galileo constellation (data/gal_nominal_constellation.yaml,
              I/NAV records, each satellite given a seeded clock offset and one BGD written as both BGDs:
              IFdataGen delays E1 by BGD(E1,E5a), gnssrx corrects it with BGD(E1,E5b));
  * REC.json  the IFdataGen scenario: static receiver, UTC start, complex 8-bit samples centred between L1
              (1575.42 MHz) and B1I (1561.098 MHz), i.e. L1 at IF +7.161 MHz and B1I at -7.161 MHz;
  * REC.truth.yaml  truth position and what a receiver config needs (format, rate, GPS IF, start time);
  * REC.bin   the samples (IFdataGen -c REC.json -o REC.bin; 40 MB per second at 20 MS/s).

IFdataGen models (SignalSim sources, src/SatelliteParam.cpp, src/Coordinate.cpp, src/SatelliteSignal.cpp): the
GPS Klobuchar delay for every system, scaled to the carrier ((1575.42 / 1561.098)^2 for B1I, none for E1); TGD
(GPS) / TGD1 (B1I) / BGD(E1,E5a) group delays; a Saastamoinen troposphere with a 1/cos(z) mapping; no receiver
clock error; Galileo E1 as BOC(1,1) E1-B and E1-C (with CS25) at half the power each, GST = GPS time.

    GNSSRX_SIGNALSIM=/path/to/IFdataGen python scripts/tools/signalsim_gps_bds.py /tmp/x/ss.bin --duration 45
    GNSSRX_SIGNALSIM=/path/to/IFdataGen python scripts/tools/signalsim_gps_bds.py /tmp/x/ssg.bin --galileo
    python scripts/tools/signalsim_gps_bds.py /tmp/x/ss.bin --no-run        # nav + config + truth only
    gnssrx run configs/gps_bds_nav.yaml --input /tmp/x/ss.bin -o /tmp/x/ss_gb.h5
    gnssrx run configs/gps_gal_bds_nav.yaml --input /tmp/x/ssg.bin -o /tmp/x/ssg.h5 \
        --set navigation.ephemeris=/tmp/x/ssg.nav \
        --set input.start_gps_week=2190 --set input.start_gps_tow_s=525600       # assisted (the mixed file)

Build IFdataGen (C++20, CMake; its IFdataGen.cpp needs <algorithm> with recent GCC):
    cmake -S SignalSim/IFdataGen -B build -DCMAKE_BUILD_TYPE=Release "-DCMAKE_CXX_FLAGS=-include algorithm"
    make -C build
"""
from __future__ import annotations

import argparse
import datetime as dt
import json
import os
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

from receiver.config import find_file
from receiver.gnss.bds_nav import quantize_bds
from receiver.gnss.ephemeris import select
from receiver.gnss.gal_inav import quantize_gal
from receiver.gnss.geodesy import lla2ecef
from receiver.gnss.rinex import read_rinex_nav, write_rinex_nav
from receiver.gnss.signals import L1_HZ
from receiver.gnss.signals_bds import B1I_HZ
from receiver.gnss.time import calendar_from_gps_time
from receiver.sim.bds_constellation import NOMINAL_BDS, bds_nominal_ephemerides
from receiver.sim.gal_constellation import NOMINAL_GAL, gal_nominal_content

ENV = "GNSSRX_SIGNALSIM"
GPS_UTC_LEAP_S = 18                      # GPS - UTC on 2022-01-01
CENTRE_HZ = (L1_HZ + B1I_HZ) / 2.0       # 1568.259 MHz: L1 at +7.161 MHz, B1I at -7.161 MHz
TOKYO = (35.681298, 139.766247, 10.0)    # the reference recording's antenna (lat, lon deg, ellipsoidal h m)


def _d12(x: float) -> str:
    return f"{x: .4E}".rjust(12)


def _hdr(content: str, label: str) -> str:
    return content.ljust(60)[:60] + label.ljust(20) + "\n"


def galileo_records(week: int, tow: float, rng):
    """Nominal Galileo I/NAV ephemerides epoched at (week, tow), each given a clock offset af0 (|af0| <= 0.5
    ms) and a BGD (|BGD| <= 5 ns, written as both BGD(E1,E5a) and BGD(E1,E5b)), on their I/NAV LSBs; and the
    Galileo header parameters of :func:`receiver.gnss.rinex.write_rinex_nav` (NeQuick-G, GST-UTC, GGTO)."""
    content = gal_nominal_content(find_file(NOMINAL_GAL), week, tow)
    out = []
    for _, c in sorted(content.items()):
        bgd = float(rng.uniform(-5e-9, 5e-9))
        out.append(quantize_gal(replace(c.eph, af0=float(rng.uniform(-5e-4, 5e-4)), tgd=bgd, bgd_e1e5a=bgd)))
    c0 = next(iter(content.values()))
    return out, {"nequick": c0.nequick, "utc": c0.utc, "ggto": c0.ggto, "gst_week": c0.eph.gst_week}


def write_nav(path, gps_rinex, week: int, tow: float, seed: int = 1, galileo: bool = False):
    """The mixed navigation file at path: GPS records valid at (week, tow) from gps_rinex, nominal BeiDou
    records epoched there, each BeiDou satellite given a clock offset af0 (|af0| <= 0.5 ms) and a TGD1
    (|TGD1| <= 10 ns; seeded), on their D1 LSBs, and with ``galileo`` the nominal Galileo records
    (:func:`galileo_records`); returns (n GPS, n BeiDou, n Galileo, IonoUtc of the GPS file)."""
    gps, iono = read_rinex_nav(gps_rinex)
    recs = [e for e in (select(lst, tow, week) for lst in gps.values()) if e is not None]
    bds, _ = bds_nominal_ephemerides(find_file(NOMINAL_BDS), week, tow)
    rng = np.random.default_rng(seed)
    bds = [quantize_bds(replace(e, af0=float(rng.uniform(-5e-4, 5e-4)), tgd=float(rng.uniform(-1e-8, 1e-8))))
           for _, e in sorted(bds.items())]
    gal, gal_hdr = galileo_records(week, tow, rng) if galileo else ([], None)
    write_rinex_nav(path, recs + bds + gal, iono, program="signalsim_gps_bds", gal=gal_hdr)
    if iono is not None:
        # the BeiDou Klobuchar set (time mark A, SV 1) and BDT-UTC: IFdataGen broadcasts them in D1/D2 only
        # when given (its header reader keeps BDSA; the model it simulates is the GPS set for every system)
        extra = [_hdr("BDSA " + "".join(_d12(v) for v in iono.alpha) + " A  1", "IONOSPHERIC CORR"),
                 _hdr("BDSB " + "".join(_d12(v) for v in iono.beta) + " A  1", "IONOSPHERIC CORR"),
                 _hdr(f"BDUT {0.0:17.10E}{0.0:16.9E}{0:7d}{week - 1356:5d}", "TIME SYSTEM CORR")]
        lines = Path(path).read_text().splitlines(keepends=True)
        end = next(i for i, ln in enumerate(lines) if "END OF HEADER" in ln)
        Path(path).write_text("".join(lines[:end] + extra + lines[end:]))
    return len(recs), len(bds), len(gal), iono


def scenario(nav_name: str, out_name: str, week: int, tow: float, duration_s: float, lla, rate_hz: float,
             cn0_dbhz: float, elevation_mask_deg: float, galileo: bool = False) -> dict:
    """The IFdataGen JSON scenario (a dict)."""
    systems = [{"system": "GPS", "signal": "L1CA", "enable": True},
               {"system": "BDS", "signal": "B1I", "enable": True}]
    if galileo:
        systems.append({"system": "Galileo", "signal": "E1", "enable": True})
    utc = calendar_from_gps_time(week, tow) - dt.timedelta(seconds=GPS_UTC_LEAP_S)
    return {
        "version": 1.0,
        "description": "gnssrx: GPS L1CA + BDS B1I" + (" + Galileo E1" if galileo else "")
                       + ", static (scripts/tools/signalsim_gps_bds.py)",
        "time": {"type": "UTC", "year": utc.year, "month": utc.month, "day": utc.day, "hour": utc.hour,
                 "minute": utc.minute, "second": utc.second + utc.microsecond * 1e-6},
        "trajectory": {
            "name": "static",
            "initPosition": {"type": "LLA", "format": "d", "latitude": lla[0], "longitude": lla[1],
                             "altitude": lla[2]},
            "initVelocity": {"type": "SCU", "speed": 0, "course": 0},
            "trajectoryList": [{"type": "Const", "time": duration_s}]},
        "ephemeris": {"type": "RINEX", "name": nav_name},
        "output": {
            "type": "IFdata", "format": "IQ8", "sampleFreq": rate_hz / 1e6, "centerFreq": CENTRE_HZ / 1e6,
            "name": out_name, "config": {"elevationMask": elevation_mask_deg},
            "systemSelect": systems},
        "power": {"noiseFloor": -172, "initPower": {"unit": "dBHz", "value": cn0_dbhz}, "elevationAdjust": False},
    }


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("output", help="recording to write (REC.bin; REC.nav/.json/.truth.yaml beside it)")
    ap.add_argument("--binary", default=os.environ.get(ENV), help=f"IFdataGen executable (default ${ENV})")
    ap.add_argument("--gps-nav", default=find_file("../shared/data/brdc0010.22n"),
                    help="GPS broadcast RINEX file (default ../shared/data/brdc0010.22n)")
    ap.add_argument("--week", type=int, default=2190, help="GPS week of the start (default 2190)")
    ap.add_argument("--tow", type=float, default=525600.0, help="GPS seconds of week of the start "
                    "(default 525600: 2022-01-01 02:00 GPST, a toe of brdc0010.22n)")
    ap.add_argument("--duration", type=float, default=45.0, help="seconds (default 45)")
    ap.add_argument("--rate", type=float, default=20e6, help="complex sample rate Hz (default 20e6)")
    ap.add_argument("--cn0", type=float, default=45.0, help="C/N0 of every satellite, dB-Hz (default 45)")
    ap.add_argument("--mask", type=float, default=10.0, help="elevation mask deg (default 10)")
    ap.add_argument("--lla", type=float, nargs=3, default=TOKYO, metavar=("LAT", "LON", "H"))
    ap.add_argument("--galileo", action="store_true", help="add Galileo E1 (the nominal constellation)")
    ap.add_argument("--seed", type=int, default=1, help="seed of the BeiDou / Galileo clock offsets and group "
                    "delays (default 1)")
    ap.add_argument("--no-run", action="store_true", help="write nav, scenario and truth only")
    a = ap.parse_args(argv)
    out = Path(a.output).resolve()
    if out.suffix != ".bin":
        ap.error("the recording's name must end in .bin")
    out.parent.mkdir(parents=True, exist_ok=True)
    stem = out.with_suffix("")
    nav = stem.with_suffix(".nav")
    n_gps, n_bds, n_gal, _ = write_nav(nav, a.gps_nav, a.week, a.tow, seed=a.seed, galileo=a.galileo)
    cfg = scenario(nav.name, out.name, a.week, a.tow, a.duration, a.lla, a.rate, a.cn0, a.mask, a.galileo)
    conf = stem.with_suffix(".json")
    conf.write_text(json.dumps(cfg, indent=2) + "\n")
    ecef = np.asarray(lla2ecef(a.lla[0], a.lla[1], a.lla[2]), float).ravel()
    truth = stem.parent / (stem.name + ".truth.yaml")
    truth.write_text(
        f"# SignalSim IFdataGen recording made by scripts/tools/signalsim_gps_bds.py\n"
        f"file: {out.name}\nformat: int8_iq\nsample_rate_hz: {a.rate:.1f}\n"
        f"if_hz: {L1_HZ - CENTRE_HZ:.1f}        # GPS L1; B1I at {B1I_HZ - CENTRE_HZ:.1f}\n"
        f"start_gps_week: {a.week}\nstart_gps_tow_s: {a.tow}\nduration_s: {a.duration}\ncn0_dbhz: {a.cn0}\n"
        f"truth:\n  lat_deg: {a.lla[0]}\n  lon_deg: {a.lla[1]}\n  height_m: {a.lla[2]}\n"
        f"  ecef_m: [{ecef[0]:.4f}, {ecef[1]:.4f}, {ecef[2]:.4f}]\n")
    print(f"{nav.name}: {n_gps} GPS + {n_bds} BeiDou + {n_gal} Galileo records; {conf.name}; {truth.name}")
    if a.no_run:
        return 0
    if not a.binary or not os.path.isfile(a.binary):
        print(f"no IFdataGen executable: give --binary or set {ENV}", file=sys.stderr)
        return 2
    r = subprocess.run([a.binary, "-c", str(conf), "-o", str(out)], cwd=str(out.parent),
                       stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    if r.returncode != 0 or not out.exists():
        print(r.stdout[-2000:], file=sys.stderr)
        print(f"IFdataGen failed (exit {r.returncode})", file=sys.stderr)
        return 2
    print(f"{out.name}: {out.stat().st_size / 1e6:.0f} MB")
    return 0


if __name__ == "__main__":
    sys.exit(main())
