"""RINEX 3.04 observation file from a run's ``/observables`` table (plus the navigation file).

Observation types: C1C (pseudorange, m), L1C (carrier phase, cycles), D1C (Doppler, Hz), S1C (C/N0,
dB-Hz) for GPS and QZSS (L1 C/A; QZSS PRN 193.. is J01..); C2I, L2I, D2I, S2I for BeiDou B1I (RINEX 3
band 2); C1C, L1C, D1C, S1C for Galileo E1 (band 1, attribute C: the E1-C pilot, which gnssrx's Galileo
channel tracks for code and carrier; E1-B only gives the I/NAV symbols, so the RINEX 3 code of a B+C tracker,
1X, would claim power the measurements do not use).  A file with more than one system is a mixed ('M') file
with one SYS / # / OBS TYPES line per system; the time system is GPS in every file (TIME OF FIRST OBS says
so, also in a Galileo-only file whose default would be GAL).  Conventions:

* Epochs are the receiver clock readings of the measurements: GPS time of the fix plus its clock bias / c
  (the pseudoranges are the raw ones, c (receiver time - transmit time)), so another program estimates
  the same receiver clock bias as gnssrx.  Epochs are written to 0.1 microsecond.
* L1C follows the RINEX sign convention (phase grows with the range): it is minus the accumulated carrier
  NCO phase of the tracking loop, which grows with the Doppler.  The phase origin is arbitrary per
  channel.  D1C is positive for approaching satellites.
* Loss-of-lock indicator (on L1C): bit 0 when the carrier loop's lock time is shorter than the time since
  the satellite's previous observation (lock was lost and regained in between), or when the satellite
  appears after the first epoch with a lock time shorter than the gap; bit 1 while the half-cycle
  ambiguity is not resolved (no LNAV / D1 preamble seen yet; the Galileo pilot, whose secondary code is
  known, has none once the channel tracks).
* SYS / PHASE SHIFT: no cycle shift is applied to any phase (0.00000 written for each system's phase code).
* Signal strength indicator (C1C and L1C): 1..9 from C/N0 in 6 dB-Hz steps (RINEX 3 table).

Second band (a dual-frequency run's ``/observables_l5``, ``/observables_e5a``; receiver.dualband): the system's
SYS / # / OBS TYPES line goes on with C5Q, L5Q, D5Q, S5Q for GPS L5 and for Galileo E5a (band 5, attribute Q:
gnssrx's L5 channel tracks the Q5 pilot -- code and carrier, NH20 wiped -- and its E5a channel the E5a-Q pilot,
CS100 wiped; neither correlates with the I5 / E5a-I data component, so I and X would claim what the measurements
do not use), only when the run has that band for that system, with a SYS / PHASE SHIFT line (0.00000) for L5Q.
A band measurement belongs to the epoch of the first-band row with the same receiver time and satellite (the
band's observables are computed at the first band's navigation epochs); a satellite without one has blank
band fields.  C5Q is the band's pseudorange (its code phase, the whole milliseconds from C1C: unsmoothed, or
Hatch-smoothed with the band's carrier when navigation.smoothing_s is set); L5Q is minus the band channel's
carrier NCO phase (cycles of the band's wavelength, the L1C convention), half a cycle added when the pilot
reads negative once its secondary code is wiped; D5Q the band channel's own carrier NCO Doppler.  The LLI
of L5Q follows the L1C rules with the band channel's lock time (bit 0) and bit 1 until the pilot's secondary
code is wiped; the SSI is that of the band's C/N0.  Runs without a second band give the file they gave
before the band existed, byte for byte.
"""
from __future__ import annotations

import datetime as _dt
import os

import numpy as np

from .. import __version__
from ..gnss.satid import sat_label, sat_system
from ..gnss.time import split_gps_time
from ..errors import UserError
from ..runfile.reader import RunData, RunFile
from ..runfile.record import OBS_DTYPE

OBS_TYPES = ("C1C", "L1C", "D1C", "S1C")
#: observation codes per system letter (same four quantities, same order as OBS_TYPES)
SYS_OBS_TYPES = {"G": OBS_TYPES, "J": OBS_TYPES, "C": ("C2I", "L2I", "D2I", "S2I"),
                 "E": ("C1C", "L1C", "D1C", "S1C")}
#: second bands: run-file table suffix (``/observables_<tag>``) -> RINEX codes (module docstring: pilots, Q)
BAND_OBS_TYPES = {"l5": ("C5Q", "L5Q", "D5Q", "S5Q"), "e5a": ("C5Q", "L5Q", "D5Q", "S5Q")}
BAND_NAMES = {"l5": "GPS L5 (Q5 pilot)", "e5a": "Galileo E5a (E5a-Q pilot)"}
LLI_LOSS = 1
LLI_HALF_CYCLE = 2


def _hdr(content: str, label: str) -> str:
    return content.ljust(60)[:60] + label.ljust(20)[:20]


def _field(value, lli: int = 0, ssi: int = 0) -> str:
    if value is None or not np.isfinite(value) or abs(value) >= 1e10:
        return " " * 16
    return f"{value:14.3f}" + (str(lli) if lli else " ") + (str(ssi) if ssi else " ")


def ssi_from_cn0(cn0) -> int:
    """RINEX 3 signal strength indicator: 1 (< 12 dB-Hz) ... 9 (>= 54 dB-Hz); 0 when unknown."""
    if cn0 is None or not np.isfinite(cn0):
        return 0
    return int(min(max(int(cn0 // 6), 1), 9))


def _epoch_groups(obs):
    """Row index arrays of the observable epochs, in time order."""
    if not len(obs):
        return []
    key = obs["time_s"]
    order = np.lexsort((obs["prn"], key))
    k = key[order]
    cuts = np.nonzero(np.diff(k) > 1e-9)[0] + 1
    return np.split(order, cuts)


def lli_flags(obs) -> np.ndarray:
    """Loss-of-lock indicator of every observable row (see the module docstring)."""
    lli = np.zeros(len(obs), dtype=np.uint8)
    last_t: dict[int, float] = {}
    prev_epoch_t = None
    for rows in _epoch_groups(obs):
        t = float(obs["time_s"][rows[0]])
        for r in rows:
            prn = int(obs["prn"][r])
            lock = float(obs["lock_time_s"][r])
            ref = last_t.get(prn, prev_epoch_t)
            if ref is not None and np.isfinite(lock) and lock + 1e-3 < t - ref:
                lli[r] |= LLI_LOSS
            if not obs["half_cycle_resolved"][r]:
                lli[r] |= LLI_HALF_CYCLE
            last_t[prn] = t
        prev_epoch_t = t
    return lli


def band_tables(run: RunData) -> dict:
    """{tag: OBS_DTYPE rows of ``/observables_<tag>``} of the run's second bands (BAND_OBS_TYPES), read from
    its run file; empty without one (or without a run file behind the data)."""
    tags = [t for t in BAND_OBS_TYPES if f"observables_{t}" in (run.groups or ())]
    if not tags:
        return {}
    out = {}
    try:
        with RunFile(run.path) as rf:
            for t in tags:
                cols = rf.columns(f"observables_{t}", OBS_DTYPE.names)
                n = len(cols["time_s"]) if "time_s" in cols else 0
                a = np.zeros(n, OBS_DTYPE)
                for name in OBS_DTYPE.names:
                    if name in cols:
                        a[name] = cols[name]
                    elif a[name].dtype.kind == "f":
                        a[name] = np.nan
                if n:
                    out[t] = a
    except UserError:
        return {}
    return out


def _band_index(obs, bands: dict, system: str):
    """({(time_s, prn): (tag, row)} of the band rows that have a first-band row of the same receiver time and
    satellite, {system letter: band tags with such rows}, {tag: LLI of its rows})."""
    have = {(float(t), int(p)) for t, p in zip(obs["time_s"], obs["prn"])}
    index, letters, lli = {}, {}, {}
    for tag, b in bands.items():
        lli[tag] = lli_flags(b)
        for i, (t, p) in enumerate(zip(b["time_s"].tolist(), b["prn"].tolist())):
            if (t, p) in have and (t, p) not in index:
                index[(t, p)] = (tag, i)
                tags = letters.setdefault(sat_system(p, system), [])
                if tag not in tags:
                    tags.append(tag)
    return index, letters, lli


def _body_lines(obs, groups, rx_tow, system, lli, bands, b_index, b_letters, b_lli):
    """The epoch records of the observation file: (lines, [(epoch datetime, fraction s)], {prn: the second
    bands' observation counts})."""
    b_counts: dict[int, np.ndarray] = {}
    lines_body = []
    epochs = []
    for rows in groups:
        r0 = rows[0]
        t, frac = split_gps_time(int(obs["gps_week"][r0]), float(rx_tow[r0]), 7)
        epochs.append((t, frac))
        sec = t.second + frac
        lines_body.append(f"> {t.year:4d} {t.month:02d} {t.day:02d} {t.hour:02d} {t.minute:02d}"
                          f"{sec:11.7f}  0{len(rows):3d}")
        for r in rows:
            ssi = ssi_from_cn0(float(obs["cn0_dbhz"][r]))
            phase = -float(obs["carrier_phase_cycles"][r])
            prn = int(obs['prn'][r])
            line = (sat_label(prn, system)
                    + _field(float(obs["pseudorange_m"][r]), 0, ssi)
                    + _field(phase, int(lli[r]), ssi)
                    + _field(float(obs["doppler_hz"][r]))
                    + _field(float(obs["cn0_dbhz"][r])))
            for tag in b_letters.get(sat_system(prn, system), ()):
                hit = b_index.get((float(obs["time_s"][r]), prn))
                if hit is None or hit[0] != tag:
                    line += " " * 64
                    continue
                b, i = bands[tag][hit[1]], hit[1]
                vals = (float(b["pseudorange_m"]), -float(b["carrier_phase_cycles"]), float(b["doppler_hz"]),
                        float(b["cn0_dbhz"]))
                b_ssi = ssi_from_cn0(vals[3])
                line += (_field(vals[0], 0, b_ssi) + _field(vals[1], int(b_lli[tag][i]), b_ssi)
                         + _field(vals[2]) + _field(vals[3]))
                c = b_counts.setdefault(prn, np.zeros(4 * len(BAND_OBS_TYPES), int))
                k = 4 * list(BAND_OBS_TYPES).index(tag)
                c[k:k + 4] += [int(np.isfinite(v) and abs(v) < 1e10) for v in vals]
            lines_body.append(line.rstrip())
    return lines_body, epochs, b_counts


def write_rinex_obs(path, run: RunData, marker: str | None = None, bands: dict | None = None) -> dict:
    """Write the observation file.  Returns a small summary (epochs, satellites, first/last epoch).

    bands: {tag: OBS_DTYPE rows} of the second bands (default: :func:`band_tables` of the run)."""
    obs = run.obs
    groups = _epoch_groups(obs)
    if not groups:
        raise ValueError("the run has no observables")
    rx_tow = run.rx_tow()
    system = run.system
    lli = lli_flags(obs)
    bands = band_tables(run) if bands is None else bands
    b_index, b_letters, b_lli = _band_index(obs, bands, system)
    sys_types = {c: SYS_OBS_TYPES[c] + sum((BAND_OBS_TYPES[t] for t in b_letters.get(c, ())), ())
                 for c in SYS_OBS_TYPES}
    lines_body, epochs, b_counts = _body_lines(obs, groups, rx_tow, system, lli, bands, b_index, b_letters, b_lli)
    first_t, first_f = epochs[0]
    last_t, last_f = epochs[-1]
    if len(epochs) > 1:
        times = np.array([(t - epochs[0][0]).total_seconds() + f for t, f in epochs])
        interval = round(float(np.median(np.diff(times))), 6)
    else:
        interval = None
    fx = run.fixes
    fin = np.all(np.isfinite(fx["ecef"]), axis=1) if len(fx) else np.zeros(0, bool)
    approx = np.median(fx["ecef"][fin], axis=0) if fin.any() else np.zeros(3)
    marker = marker or run.name
    now = _dt.datetime.now(_dt.timezone.utc).strftime("%Y%m%d %H%M%S UTC")
    mode = "assisted (RINEX ephemerides)" if run.assisted else "autonomous (decoded ephemerides)"
    prns = sorted({int(p) for p in obs["prn"]})
    letters = sorted({sat_system(p, system) for p in prns}, key="GCEJ".index)
    file_sys = letters[0] if len(letters) == 1 else "M"
    signal_name = {"G": "GPS L1 C/A", "J": "QZSS L1 C/A", "C": "BeiDou B1I", "E": "Galileo E1"}
    h = [
        _hdr(f"{3.04:9.2f}{'':11}{'O':<20}{file_sys:<20}", "RINEX VERSION / TYPE"),
        _hdr(f"{'gnssrx ' + __version__:<20}{'':<20}{now:<20}", "PGM / RUN BY / DATE"),
        _hdr("gnssrx software receiver, " + ", ".join(signal_name[c] for c in letters), "COMMENT"),
        _hdr(f"run file {os.path.basename(run.path)}, {mode}", "COMMENT"),
    ]
    band_tags = [t for t in BAND_OBS_TYPES if any(t in v for v in b_letters.values())]
    if band_tags:
        h.append(_hdr("second band: " + ", ".join(BAND_NAMES[t] for t in band_tags), "COMMENT"))
    h += [
        _hdr("phase = -(accumulated carrier NCO phase); epochs = receiver", "COMMENT"),
        _hdr("clock (GPS time of fix + clock bias / c)", "COMMENT"),
        _hdr(marker[:60], "MARKER NAME"),
        _hdr("NON_GEODETIC", "MARKER TYPE"),
        _hdr(f"{'unknown':<20}{'unknown':<40}", "OBSERVER / AGENCY"),
        _hdr(f"{'0':<20}{'gnssrx':<20}{__version__:<20}", "REC # / TYPE / VERS"),
        _hdr(f"{'0':<20}{'unknown':<20}", "ANT # / TYPE"),
        _hdr("".join(f"{v:14.4f}" for v in approx), "APPROX POSITION XYZ"),
        _hdr("".join(f"{0.0:14.4f}" for _ in range(3)), "ANTENNA: DELTA H/E/N"),
    ]
    h += [_hdr(f"{c}  {len(sys_types[c]):3d}" + "".join(f" {t}" for t in sys_types[c]),
               "SYS / # / OBS TYPES") for c in letters]
    h.append(_hdr("DBHZ", "SIGNAL STRENGTH UNIT"))
    if interval is not None and interval > 0:
        h.append(_hdr(f"{interval:10.3f}", "INTERVAL"))
    h.append(_hdr(f"{first_t.year:6d}{first_t.month:6d}{first_t.day:6d}{first_t.hour:6d}{first_t.minute:6d}"
                  f"{first_t.second + first_f:13.7f}{'':5}GPS", "TIME OF FIRST OBS"))
    h.append(_hdr(f"{last_t.year:6d}{last_t.month:6d}{last_t.day:6d}{last_t.hour:6d}{last_t.minute:6d}"
                  f"{last_t.second + last_f:13.7f}{'':5}GPS", "TIME OF LAST OBS"))
    for c in letters:
        for code in sys_types[c][1::4]:
            h.append(_hdr(f"{c} {code} {0.0:8.5f}", "SYS / PHASE SHIFT"))
    leap = run.leap_seconds()
    if leap:
        h.append(_hdr(f"{leap:6d}", "LEAP SECONDS"))
    h.append(_hdr(f"{len(prns):6d}", "# OF SATELLITES"))
    for p in prns:
        sel = obs["prn"] == p
        counts = [int(np.count_nonzero(np.isfinite(obs[c][sel]))) for c in
                  ("pseudorange_m", "carrier_phase_cycles", "doppler_hz", "cn0_dbhz")]
        bc = b_counts.get(p, np.zeros(4 * len(BAND_OBS_TYPES), int))
        for tag in b_letters.get(sat_system(p, system), ()):
            k = 4 * list(BAND_OBS_TYPES).index(tag)
            counts += bc[k:k + 4].tolist()
        h.append(_hdr(f"   {sat_label(p, system)}" + "".join(f"{c:6d}" for c in counts), "PRN / # OF OBS"))
    h.append(_hdr("", "END OF HEADER"))
    with open(path, "w", newline="\n") as fh:
        fh.write("\n".join(h + lines_body) + "\n")
    return {"epochs": len(groups), "satellites": prns, "interval_s": interval}


def nav_ephemerides(run: RunData) -> list:
    """Ephemerides for the navigation file: the ones the fixes used (:meth:`RunData.used_ephemerides`)."""
    return run.used_ephemerides()


def decoded_gal_params(path) -> dict:
    """The Galileo system parameters of a run, decoded again from the E1-B prompts (``prompt1_i``, one I/NAV
    symbol per 4-ms record) of its stored Galileo channels: {"nequick", "utc", "ggto", "gst_week"} as far as
    some channel decoded them (empty without Galileo channels)."""
    from ..gnss.gal_inav import InavDecoder
    from ..runfile.reader import RunFile
    out: dict = {}
    with RunFile(path) as rf:
        for name in rf.channel_names():
            if name[:1] != "E":
                continue
            ch = rf.channel(name, ("code_period", "prompt1_i"))
            if len(ch.get("code_period", ())) < 500:
                continue
            dec = InavDecoder(rf.channel_prn(name))
            cp, sym = ch["code_period"], ch["prompt1_i"]
            for r in np.split(np.arange(len(cp)), np.nonzero(np.diff(cp) != 1)[0] + 1):
                if len(r):
                    dec.feed(sym[r], int(cp[r[0]]))
            for key in ("nequick", "utc", "ggto", "gst_week"):
                if key not in out and getattr(dec, key) is not None:
                    out[key] = getattr(dec, key)
            if len(out) == 4:
                break
    return out


def gal_header_params(run: RunData, ephs) -> dict | None:
    """The Galileo header parameters of the navigation file (:func:`receiver.gnss.rinex_gal.gal_header_lines`)
    when it has Galileo ephemerides: :func:`decoded_gal_params` of the run (the GST week of the first Galileo
    ephemeris when no channel decoded one); None otherwise."""
    gal = [e for e in ephs if getattr(e, "system", "G") == "E"]
    if not gal:
        return None
    try:
        params = decoded_gal_params(run.path)
    except UserError:                      # no run file behind the data (tests): no parameters
        return None
    params.setdefault("gst_week", gal[0].gst_week)
    return params if len(params) > 1 else None


def write_nav(path, run: RunData) -> dict:
    """Write the RINEX 3.04 navigation file of the ephemerides the fixes used, with the iono/UTC parameters; returns
    {"ephemerides": count, "satellites": keys, "iono": written}.  ValueError when the run has none."""
    from ..gnss.rinex import write_rinex_nav
    ephs = nav_ephemerides(run)
    if not ephs:
        raise ValueError("the run has no ephemerides")
    write_rinex_nav(path, ephs, run.iono(), system=run.system, gal=gal_header_params(run, ephs))
    return {"ephemerides": len(ephs), "satellites": sorted({run.eph_key(e) for e in ephs}),
            "iono": run.iono() is not None}


__all__ = ["write_rinex_obs", "write_nav", "nav_ephemerides", "lli_flags", "ssi_from_cn0", "OBS_TYPES",
           "BAND_OBS_TYPES", "band_tables"]
