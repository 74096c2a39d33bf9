"""Simulator scenario: schema (with documented defaults), loading and path resolution.

A scenario is a YAML file validated against :data:`SCENARIO_SCHEMA` with the project's config machinery
(unknown keys or bad values raise UserError naming the dotted key; ``--set key=value`` overrides).
Relative paths inside a scenario (RINEX file, constellation file, trajectory CSV) are looked up in the
current directory first, then in the repository root.
"""
from __future__ import annotations

import os
from pathlib import Path

from ..config import P, Section, build, defaults_doc, find_file, read_yaml, search_bases, shipped_dir
from ..errors import UserError
from ..source.io import BIT_ORDERS, ENCODINGS, FORMATS, NOISE_SIGMA, is_complex
from .clock import CLOCK_PRESETS
from .trajectory import TRAJECTORY_KINDS

REPO_ROOT = Path(__file__).resolve().parents[2]
NOMINAL_CONSTELLATION = "data/gps_nominal_constellation.yaml"

SCENARIO_SCHEMA = {
    "signal": P("gps_l1ca", "str", "signal generated: gps_l1ca, or bds_b1i (BeiDou B1I codes, carrier, NH/D1 "
                                   "and D2 symbols; with constellation.source bds_nominal BeiDou orbits and "
                                   "genuine D1/D2 messages, otherwise pseudo-random message bits on the orbits "
                                   "of the same PRN numbers of the constellation source), or gal_e1 (Galileo "
                                   "E1-B with genuine I/NAV pages + E1-C with CS25, BOC(1,1), the orbits of "
                                   "constellation.gal_file; docs/galileo.md)",
                choices=("gps_l1ca", "bds_b1i", "gal_e1")),
    "signals": P([], "list", "several signals in one recording: [gps_l1ca, bds_b1i] puts the GPS satellites of "
                             "constellation.source (embedded or rinex) and the nominal BeiDou constellation "
                             "(constellation.bds_file, D1/D2 messages) in one file; frontend.if_hz is the IF "
                             "of the first signal, the other sits at if_hz + its carrier - the first's (one "
                             "LO: complex samples centred between L1 and B1I need >= ~20 MS/s); "
                             "constellation.prns / exclude_prns select GPS PRNs.  Empty: `signal` alone"),
    "time": {
        "gps_week": P(2190, "int", "full GPS week of the first sample", lo=0),
        "tow_s": P(525584.0, "float", "GPS time of week of the first sample as read by the receiver clock "
                                      "(true GPS time of the first sample = tow_s - clock.bias_s)",
                   lo=0.0, hi=604800.0),
        "duration_s": P(45.0, "float", "length of the recording (s)", lo=0.001),
        "seed": P(1, "int", "random seed (noise, clock, scintillation); same seed, same recording", lo=0),
    },
    "constellation": {
        "source": P("embedded", "str", "ephemeris source: the embedded nominal 31-satellite constellation "
                                       "(re-epoched to the start time), a RINEX navigation file, or "
                                       "bds_nominal: the nominal BeiDou GEO/IGSO/MEO constellation (bds_file), "
                                       "or bds_rinex: the BeiDou records of the RINEX 3 file `rinex`, both "
                                       "broadcast in D1/D2 messages (signal: bds_b1i)",
                    choices=("embedded", "rinex", "bds_nominal", "bds_rinex")),
        "bds_file": P("data/bds_nominal_constellation.yaml", "str", "nominal BeiDou orbits (source: "
                                                                     "bds_nominal)"),
        "gal_file": P("data/gal_nominal_constellation.yaml", "str", "nominal Galileo orbits (signal: gal_e1)"),
        "rinex": P(None, "str", "RINEX 2/3 GPS navigation file (source: rinex; RINEX 3 BeiDou records: "
                                "source bds_rinex); per PRN the healthy set whose toe is nearest to the "
                                "middle of the run", nullable=True),
        "nominal_file": P(NOMINAL_CONSTELLATION, "str", "the embedded constellation file (source: embedded)"),
        "prns": P(None, "list_int", "simulate only these PRNs (empty: all; QZSS: 193-202; BeiDou 1-63; in a "
                                    "recording of several signals BeiDou PRN p is 400 + p)",
                  nullable=True,
                  lo=1, hi=463),
        "exclude_prns": P([], "list_int", "PRNs never simulated (several signals: BeiDou PRN p is 400 + p)",
                          lo=1, hi=463),
        "qzss": P(False, "bool", "add the QZSS satellites of qzss_file (PRN 193-202, on the L1 C/A signal; "
                                 "source: embedded)"),
        "qzss_file": P("data/qzss_nominal_constellation.yaml", "str", "nominal QZSS orbits (same format "
                                                                       "as nominal_file)"),
        "elevation_mask_deg": P(5.0, "float", "satellites below this elevation carry no signal",
                                lo=-10.0, hi=90.0),
    },
    "receiver": {
        "trajectory": P("static", "str", "receiver motion", choices=TRAJECTORY_KINDS),
        "lat_deg": P(35.681298, "float", "latitude (static / start / figure-eight centre)", lo=-90.0, hi=90.0),
        "lon_deg": P(139.766247, "float", "longitude", lo=-180.0, hi=360.0),
        "height_m": P(10.0, "float", "height above the WGS-84 ellipsoid", lo=-1000.0, hi=1e6),
        "velocity_enu_mps": P([0.0, 0.0, 0.0], "list_float", "velocity (E, N, U) for constant_velocity, "
                                                             "initial velocity for segments"),
        "segments": P([], "list", "segments: list of {duration_s, accel_enu_mps2: [E,N,U], "
                                  "jerk_enu_mps3: [E,N,U]}; within a segment a = accel + jerk*tau"),
        "figure8": {
            "size_m": P(200.0, "float", "length of the figure eight along its heading", lo=0.1),
            "peak_speed_mps": P(10.0, "float", "speed at the crossing point (the maximum)", lo=0.0),
            "heading_deg": P(0.0, "float", "direction of the long axis, clockwise from north"),
        },
        "csv": {
            "path": P(None, "str", "trajectory CSV (trajectory: csv)", nullable=True),
            "columns": P("ecef", "str", "coordinates: time,x,y,z (ecef) or time,lat,lon,h (lla; deg, m)",
                         choices=("ecef", "lla")),
            "time": P("relative", "str", "time column: seconds since the first sample (relative) or GPS "
                                         "time of week (gps_tow)", choices=("relative", "gps_tow")),
        },
    },
    "clock": {
        "bias_s": P(0.0, "float", "receiver clock bias at the first sample: clock reading - true GPS time",
                    lo=-0.5, hi=0.5),
        "freq_error_ppm": P(0.0, "float", "oscillator fractional frequency error (= initial clock drift); "
                                          "scales the sample clock and the local oscillator", lo=-200, hi=200),
        "aging_ppb_per_s": P(0.0, "float", "linear change of the frequency error (ppb/s)"),
        "noise": P("none", "str", "Allan-variance noise preset (h0, h_-1, h_-2); 'custom' uses h0/h_1/h_2",
                   choices=tuple(CLOCK_PRESETS) + ("custom",)),
        "h0": P(None, "float", "white FM level (overrides the preset)", nullable=True, lo=0.0),
        "h_1": P(None, "float", "flicker FM level h_-1 (overrides the preset)", nullable=True, lo=0.0),
        "h_2": P(None, "float", "random-walk FM level h_-2 (overrides the preset)", nullable=True, lo=0.0),
        "white_fm_corner_hz": P(1.0, "float", "white FM rolls off above this Fourier frequency (20 dB/decade) "
                                              "as real crystals do (empty: white FM up to 500 Hz)",
                                nullable=True, lo=0.01, hi=500.0),
    },
    "cn0": {
        "mode": P("constant", "str", "C/N0 model: constant, elevation (linear in elevation between "
                                     "horizon_dbhz and dbhz at zenith), or schedule",
                  choices=("constant", "elevation", "schedule")),
        "dbhz": P(45.0, "float", "C/N0 (constant) or C/N0 at zenith (elevation)", lo=-20.0, hi=100.0),
        "horizon_dbhz": P(35.0, "float", "C/N0 at 0 deg elevation (elevation mode)", lo=-20.0, hi=100.0),
        "per_prn": P({}, "dict", "fixed C/N0 of given PRNs, {prn: dbhz} (overrides the mode)"),
        "schedule": P([], "list", "schedule mode: list of {prns: [..] (omit: all), t_s: [..], dbhz: [..]}, "
                                  "C/N0 linear between the points, constant outside"),
    },
    "blockage": {
        "outages": P([], "list", "outage windows: list of {prn, start_s, end_s} (receiver time since the "
                                 "first sample), no signal inside; prn: all blocks every satellite"),
        "total": P([], "list", "total outages (bridges, tunnels): list of {start_s, end_s}, no satellite "
                               "carries a signal inside"),
        "visible_count": P([], "list", "schedule of [t_s, n]: from t_s on at most n satellites carry a "
                                       "signal (the lowest elevations are dropped first)"),
        "random": {
            "enabled": P(False, "bool", "urban canyon: random per-satellite blockages (receiver/sim/blockage.py; "
                                        "the realised windows go to the truth file's /blockage)"),
            "seed": P(None, "int", "seed of the pattern (empty: time.seed)", nullable=True, lo=0),
            "start_s": P(0.0, "float", "random blockages from this receiver time on (s since the first "
                                       "sample)", lo=0.0),
            "end_s": P(None, "float", "... until this time (empty: the end of the recording)", nullable=True,
                       lo=0.0),
            "min_duration_s": P(0.2, "float", "shortest blockage (and shortest visible gap)", lo=0.001),
            "max_duration_s": P(5.0, "float", "longest blockage", lo=0.001),
            "distribution": P("uniform", "str", "blockage lengths between min and max: uniform, or loguniform "
                                                "(short ones more common; shorter visible gaps for the same "
                                                "target)", choices=("uniform", "loguniform")),
            "min_visible": P(4, "int", "the pattern is calibrated on this many satellites visible ...",
                             lo=1, hi=32),
            "target_fraction": P(0.7, "float", "... during this fraction of the window (after the elevation "
                                               "mask, outages and total windows)", lo=0.01, hi=0.99),
        },
    },
    "scintillation": {
        "enabled": P(False, "bool", "apply ionospheric scintillation (Cornell model + phase)"),
        "prns": P(None, "list_int", "scintillated PRNs (empty: all)", nullable=True, lo=1, hi=202),
        "s4": P(0.3, "float", "amplitude scintillation index S4", lo=0.0, hi=0.99),
        "sigma_phi_rad": P(0.25, "float", "phase scintillation standard deviation (rad)", lo=0.0, hi=10.0),
        "tau0_s": P(1.0, "float", "decorrelation time (s)", lo=0.01, hi=100.0),
        "per_prn": P({}, "dict", "per-PRN overrides, {prn: {s4, sigma_phi_rad, tau0_s}}"),
        "window_s": P(60.0, "float", "analysis window over which S4 and sigma_phi are met", lo=1.0),
    },
    "atmosphere": {
        "ionosphere": P("klobuchar", "str", "ionospheric delay (code delay, carrier advance)",
                        choices=("klobuchar", "none")),
        "troposphere": P("saastamoinen", "str", "tropospheric delay", choices=("saastamoinen", "none")),
        "klobuchar_alpha": P(None, "list_float", "override the Klobuchar alpha (also broadcast)",
                             nullable=True),
        "klobuchar_beta": P(None, "list_float", "override the Klobuchar beta (also broadcast)", nullable=True),
        "iono_scale": P(1.0, "float", "the true ionosphere is this factor times the broadcast Klobuchar model "
                                      "(the broadcast parameters stay as they are): 1.5 leaves the 50 % the "
                                      "single-frequency fix cannot remove (docs: Dual frequency)", lo=0.0, hi=20.0),
    },
    "l5": {
        "enabled": P(False, "bool", "also write a GPS L5 recording (<stem>_l5.bin, Q5 pilot and I5 of every GPS "
                                    "satellite, own truth <stem>_l5.truth.h5) on the same receiver clock as the "
                                    "L1 file; the receiver fragment names it in input.signal_files"),
        "sample_rate_hz": P(21.0e6, "float", "L5 file sample rate (complex: about 2 x 10.23 MHz keeps the main "
                                             "lobe; a rate that is not a whole multiple of 10.23 MHz avoids the "
                                             "code bias of a sample grid locked to the chips)", lo=1e6, hi=1e9),
        "if_hz": P(0.0, "float", "L5 file IF (the front end's second channel, its own LO)"),
        "format": P("int8_iq", "str", "L5 file sample format", choices=tuple(FORMATS)),
        "cn0_offset_db": P(0.0, "float", "Q5 pilot C/N0 (I5: the same) minus the L1 C/A C/N0 of the "
                                                "same satellite (dB)"),
    },
    "e5a": {
        "enabled": P(False, "bool", "signal gal_e1: also write a Galileo E5a recording (<stem>_e5a.bin, E5a-Q pilot "
                                    "and E5a-I of every Galileo satellite, own truth <stem>_e5a.truth.h5) on the "
                                    "same receiver clock as the E1 file, the E1-E5a group delays those of the "
                                    "BGD(E1,E5a) in I/NAV; the receiver fragment names it in input.signal_files "
                                    "(docs: Dual frequency)"),
        "sample_rate_hz": P(21.0e6, "float", "E5a file sample rate (as l5.sample_rate_hz)", lo=1e6, hi=1e9),
        "if_hz": P(0.0, "float", "E5a file IF (the front end's second channel, its own LO)"),
        "format": P("int8_iq", "str", "E5a file sample format", choices=tuple(FORMATS)),
        "cn0_offset_db": P(0.0, "float", "E5a-Q pilot C/N0 (E5a-I: the same) minus the E1 C/N0 of the same "
                                         "satellite (dB)"),
    },
    "navigation": {
        "data": P(True, "bool", "modulate the LNAV data bits (false: pilot-like, no data)"),
        "page18_every_frame": P(True, "bool", "broadcast subframe 4 page 18 (iono/UTC) in every frame "
                                              "(false: page 18 every 12.5 min as real satellites)"),
    },
    "frontend": {
        "sample_rate_hz": P(2.6e6, "float", "nominal sample rate", lo=1e5, hi=1e9),
        "if_hz": P(0.0, "float", "intermediate frequency (complex formats: may be 0; real formats: > 0)"),
        "format": P("int8_iq", "str", "sample format (docs: Your own recording)", choices=tuple(FORMATS)),
        "bit_order": P("msb_first", "str", "packed formats: bit order (as input.bit_order)",
                       choices=BIT_ORDERS),
        "encoding": P("sign_magnitude", "str", "packed formats: field encoding (as input.encoding)",
                      choices=ENCODINGS),
        "noise": P(True, "bool", "add thermal noise (false: signals only, amplitudes unchanged)"),
        "noise_sigma": P(None, "float", "noise standard deviation per real component in output units "
                                        "(empty: 8 for 8-bit, 1000 for int16, 1 for float, 2 for int4, "
                                        "2.0 / 6.0 for packed 2 / 4 bit); sets the "
                                        "signal amplitudes through C/N0", nullable=True, lo=1e-6),
    },
    "impairments": {
        "tones": P([], "list", "CW interference: list of {freq_hz (offset from the nominal carrier: at "
                               "frontend.if_hz + freq_hz in the band), power_db (over the noise power of the "
                               "sampled band), phase_deg}"),
        "dc_offset": P([0.0, 0.0], "list_float", "DC offset / LO leakage [I, Q] in units of the noise sigma "
                                                 "(added after the filter)"),
        "filter": {
            "bandwidth_hz": P(None, "float", "two-sided bandwidth of a Butterworth band-limiting filter "
                                             "centred on the IF (empty: none)", nullable=True, lo=1e3),
            "order": P(6, "int", "order of the band-limiting filter", lo=1, hi=12),
        },
        "quantization": {
            "bits": P(None, "int", "quantise to this many bits with an AGC on the total power (levels "
                                   "+/-1, +/-3, ... for <= 7 bits; -128..127 for 8); empty: the format's "
                                   "own rounding of the scaled samples", nullable=True,
                      choices=(1, 2, 3, 4, 5, 6, 7, 8)),
        },
    },
    "output": {
        "truth_rate_hz": P(100.0, "float", "rate of the truth file (a divisor of 1000)", lo=1.0, hi=1000.0),
        "block_s": P(0.5, "float", "samples generated per block (memory vs overhead)", lo=0.01, hi=10.0),
    },
}

DEFAULT_NOISE_SIGMA = NOISE_SIGMA


def resolve_path(path: str | None, what: str = "file") -> str | None:
    """Relative paths: the current directory first, then the repository root."""
    if path is None:
        return None
    p = os.path.expanduser(path)
    if os.path.isabs(p):
        if not os.path.exists(p):
            raise UserError(f"{what} not found: {path}")
        return p
    for base in (os.getcwd(), *search_bases()):
        cand = os.path.join(base, p)
        if os.path.exists(cand):
            return os.path.normpath(cand)
    raise UserError(f"{what} not found: {path} (looked in the current directory, in {REPO_ROOT} and in the "
                    f"shipped data {shipped_dir()})")


def _check(sc: Section):
    fe = sc.frontend
    fs = fe.sample_rate_hz
    if is_complex(fe.format):
        if abs(fe.if_hz) >= fs / 2:
            raise UserError(f"config key 'frontend.if_hz' must be within +/- sample_rate/2 = {fs / 2:g}")
    elif not 0.0 < fe.if_hz < fs / 2:
        raise UserError(f"config key 'frontend.if_hz' must be in (0, sample_rate/2) for the real format "
                        f"'{fe.format}'")
    rate = sc.output.truth_rate_hz
    if abs(1000.0 / rate - round(1000.0 / rate)) > 1e-9:
        raise UserError("config key 'output.truth_rate_hz' must divide 1000 (1000, 500, 200, 100, ...)")
    if sc.constellation.source == "rinex" and not sc.constellation.rinex:
        raise UserError("config key 'constellation.rinex' is required when constellation.source is 'rinex'")
    for key in ("klobuchar_alpha", "klobuchar_beta"):
        v = sc.atmosphere[key]
        if v is not None and len(v) != 4:
            raise UserError(f"config key 'atmosphere.{key}' must hold 4 numbers")
    if len(sc.receiver.velocity_enu_mps) != 3:
        raise UserError("config key 'receiver.velocity_enu_mps' must hold 3 numbers (E, N, U)")
    if sc.clock.noise == "custom" and all(sc.clock[k] is None for k in ("h0", "h_1", "h_2")):
        raise UserError("config key 'clock.noise' is 'custom' but none of clock.h0/h_1/h_2 is set")


def load_scenario(scenario=None, overrides=()) -> Section:
    """A scenario from a YAML path, a dict, or an existing Section, plus ``--set`` overrides."""
    if isinstance(scenario, Section):
        raw = scenario.to_dict()
    elif isinstance(scenario, dict):
        raw = scenario
    elif scenario is None:
        raw = {}
    else:
        raw = read_yaml(find_file(scenario))
    sc = build(SCENARIO_SCHEMA, raw, overrides)
    _check(sc)
    return sc


def clock_h(sc: Section):
    """(h0, h_1, h_2) of the scenario's clock."""
    c = sc.clock
    base = CLOCK_PRESETS.get(c.noise, (0.0, 0.0, 0.0))
    return tuple(base[i] if c[k] is None else c[k] for i, k in enumerate(("h0", "h_1", "h_2")))


def noise_sigma(sc: Section) -> float:
    """Noise standard deviation per component in the recording's units: frontend.noise_sigma, else the
    default of the output format."""
    fe = sc.frontend
    return fe.noise_sigma if fe.noise_sigma is not None else DEFAULT_NOISE_SIGMA[fe.format]


def scenario_doc() -> list:
    """(key, kind, default, doc) rows for the scenario reference (docs/reference/scenario.md)."""
    return defaults_doc(SCENARIO_SCHEMA)
