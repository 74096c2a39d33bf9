"""The ``navigation`` section of the receiver config (schema fragment of the navigation stage).

The choices are the solvers' own: WLS weightings (:data:`receiver.navigation.wls_jit.WEIGHTING`),
oscillator classes (:data:`receiver.gnss.clock.OSCILLATORS`); the navigation filters are named here
(:data:`FILTERS`; receiver/navigation/pvt_filter.py implements those after ``wls``, it imports this module).
:func:`default` gives a key's default to code that accepts a partial configuration object (NavSolver,
PvtFilter.from_config): each default is stated here only.
receiver/schema.py assembles this fragment into the receiver's schema.
"""
from __future__ import annotations

from ..config import P
from ..gnss.clock import OSCILLATORS
from .wls_jit import WEIGHTING

#: navigation.filter: the single-epoch WLS, then the Kalman filters of receiver/navigation/pvt_filter.py
FILTERS = ("wls", "ekf", "ckf")

SCHEMA = {
    "enabled": P(True, "bool", "decode the navigation message (LNAV; BeiDou D1/D2) and compute fixes"),
    "rate_hz": P(10.0, "float", "observable / fix rate", lo=0.1, hi=1000.0),
    "ephemeris": P(None, "str", "RINEX 2/3 navigation file for assisted mode (its GPS/QZSS records; a "
                                "BeiDou B1I run its RINEX 3 BeiDou records; several signals: a mixed RINEX 3 "
                                "file)", nullable=True),
    "troposphere": P("saastamoinen", "str", "troposphere model", choices=("saastamoinen", "none")),
    "ionosphere": P("klobuchar", "str", "ionosphere model", choices=("klobuchar", "none")),
    "klobuchar_fallback": P(True, "bool", "while no broadcast Klobuchar set is known (LNAV subframe 4 page 18 "
                                          "comes every 12.5 min; none in the RINEX header), correct with a "
                                          "built-in set (GPS broadcast of 2022-01-01, brdc0010.22n; "
                                          "receiver/gnss/atmosphere.py) instead of not at all; "
                                          "/navigation/iono_params says which set each fix used"),
    "elevation_mask_deg": P(5.0, "float", "elevation mask", lo=-90.0, hi=90.0),
    "weighting": P("elevation", "str", "WLS weights: sin^2(el), C/N0, none, rtklib (RTKLIB's default "
                                           "single-point error model, to compare with rnx2rtkp), or "
                                           "cn0_elevation (variance 10^((cn0_ref_dbhz - C/N0) / 10) + "
                                           "1 / sin^2(el): a thermal and an elevation term)",
                   choices=tuple(WEIGHTING)),
    "cn0_ref_dbhz": P(35.0, "float", "weighting cn0_elevation: the C/N0 at which a range's thermal variance "
                                     "equals its elevation term at zenith (dB-Hz)", lo=0.0, hi=80.0),
    "weighting_per_system": P("vce", "str", "relative weight of each system in a fix mixing systems "
                                              "(elevation, cn0 and cn0_elevation weightings): fixed (each "
                                              "signal's code variance relative to L1 C/A, docs: Combining GNSS "
                                              "systems) or "
                                              "vce (that times a variance factor per system estimated from "
                                              "the fixes' residuals over the last vce_window_s: variance "
                                              "component estimation); one-system fixes are unchanged",
                                      choices=("fixed", "vce")),
    "vce_window_s": P(30.0, "float", "weighting_per_system vce: the sliding window of fixes (s) over which "
                                     "each system's variance factor is estimated", lo=0.1),
    "residual_threshold_m": P(30.0, "float", "drop the worst satellite when a residual exceeds this",
                              lo=0.0),
    "max_pdop": P(20.0, "float", "no fix when the PDOP of the satellites used exceeds this (4-satellite "
                                 "fixes in urban canyons reach PDOP > 100 and errors of hundreds of m)",
                  lo=1.0),
    "first_fix_max_pdop": P(8.0, "float", "the first fix of a run needs a PDOP at most this (no fix before it "
                                          "checks it, and it starts the aiding and the filters: weak "
                                          "5-satellite geometries at PDOP 15-20 gave first fixes 20-100 m off)",
                            lo=1.0),
    "filter": P("wls", "str", "navigation solution: wls (single-epoch weighted least squares and "
                              "Doppler velocity), ekf (extended Kalman filter) or ckf (square-root "
                              "cubature Kalman filter) over position, velocity, clock bias and drift, fed "
                              "with the pseudoranges and pseudorange rates of the satellites the WLS fix "
                              "used; /navigation then holds the filtered position, velocity and clock "
                              "(n_sats, DOPs and /observables stay the WLS's; receiver/navigation/pvt_filter.py)",
                choices=FILTERS),
    "filter_accel_psd": P(1.0, "float", "ekf/ckf: PSD of the white receiver acceleration per axis "
                                        "(m^2/s^3; ~0.01 static, 1 pedestrian/car, 10+ agile)", lo=0.0),
    "filter_code_sigma_m": P(3.0, "float", "ekf/ckf: pseudorange noise standard deviation at zenith (m; "
                                           "unsmoothed code unless filter_smoothed_code; divided by "
                                           "sin(elevation) unless weighting is none)", lo=1e-6),
    "filter_rate_sigma_mps": P(0.1, "float", "ekf/ckf: pseudorange-rate noise standard deviation at "
                                             "zenith (m/s; the rates are carrier delta ranges over 1/rate_hz, "
                                             "modelled as such; divided by sin(elevation) unless weighting is "
                                             "none)", lo=1e-6),
    "filter_clock": P("tcxo", "str", "ekf/ckf: oscillator class of the clock process noise (h0, h_-2)",
                      choices=tuple(OSCILLATORS)),
    "filter_code_carrier_drift": P(True, "bool", "ekf/ckf: estimate a code-minus-carrier clock drift "
                                                 "(front ends whose oscillator error reaches the carrier "
                                                 "only, e.g. the reference recording)"),
    "filter_smoothed_code": P(False, "bool", "ekf/ckf: feed the filter the carrier-smoothed pseudoranges "
                                             "the WLS uses (smoothing_s) instead of the unsmoothed ones (the "
                                             "filter smooths with the carrier itself; smoothed code errors are "
                                             "correlated in time, which it takes as white)"),
    "filter_reset_m": P(100.0, "float", "ekf/ckf: a WLS fix farther than this (plus 5 predicted sigma) "
                                        "from the prediction is not used; 3 in a row restart the filter "
                                        "from the WLS", lo=0.0),
    "settle_s": P(1.0, "float", "a channel's measurements are used this long after its pull-in "
                                "(DLL/PLL transients over); a weak channel's after its DLL hold "
                                "(tracking.weak.dll_hold_ms) and this", lo=0.0),
    "lookahead_s": P(0.0, "float", "fixed-lag smoothing of a recording: every fix is solved again this many "
                                   "seconds later, each pseudorange carrier-smoothed with the fit of its "
                                   "carrier arc at that time (code up to lookahead_s after the epoch), so the "
                                   "first seconds of an arc are as good as the later ones.  The receiver's own "
                                   "use of its fixes (aiding, re-acquisition, vector handover) stays causal; "
                                   "navigation.filter ekf/ckf, vector and dual-band runs keep the causal "
                                   "fixes.  0 = off (a real-time receiver's fixes)", lo=0.0),
    "smoothing_s": P(100.0, "float", "carrier-smoothing (Hatch) window of pseudoranges; 0 = off",
                     lo=0.0),
    "aiding": {
        "enabled": P(True, "bool", "clock/height-aided fixes (docs: Navigation, aided fixes): an epoch with at most "
                                   "max_sats satellites, or whose unaided fix is refused (max_pdop), is "
                                   "solved with the receiver clock bias and height predicted from the "
                                   "unaided fixes of the last second as extra measurements; 3 satellites "
                                   "then give a fix.  Written with mode 3 (aided), n_sats = satellites used"),
        "max_sats": P(5, "int", "aid every fix with at most this many satellites (3: only 3-satellite fixes "
                                "and refused weak geometries)", lo=3, hi=64),
        "clock": P(True, "bool", "constrain the receiver clock bias (and, for the velocity, its drift)"),
        "height": P(True, "bool", "constrain the ellipsoidal height (land vehicles; off for aircraft)"),
        "max_age_s": P(10.0, "float", "no aiding when the latest unaided fix is older than this", lo=0.0),
        "code_sigma_m": P(3.0, "float", "standard deviation of a weight-1 pseudorange (the best satellite's), "
                                        "against which the constraints are weighted", lo=1e-3),
        "rate_sigma_mps": P(0.1, "float", "the same for a pseudorange rate (the drift constraint's weight)",
                            lo=1e-4),
        "clock_sigma_m": P(1.0, "float", "standard deviation of the predicted clock bias right after an "
                                         "unaided fix", lo=1e-3),
        "clock_growth": P(0.3, "float", "its growth with the age t of the latest unaided fix: sigma = "
                                        "hypot(clock_sigma_m, clock_growth t^1.5) (m/s^1.5; a random-walk "
                                        "frequency; ~0.2 for a TCXO)", lo=0.0),
        "drift_sigma_mps": P(0.2, "float", "standard deviation of the predicted clock drift", lo=1e-4),
        "height_sigma_m": P(2.0, "float", "standard deviation of the predicted height right after an "
                                          "unaided fix", lo=1e-3),
        "height_rate_mps": P(0.5, "float", "its growth per second of age (vertical speed error)", lo=0.0),
        "max_pdop": P(8.0, "float", "no aided fix when its PDOP (the constraints counted as pseudo-satellites) "
                                    "exceeds this: 3 satellites nearly in a plane with the constraints "
                                    "(urban canyon: PDOP 8-13, errors 12-25 m)", lo=1.0),
        "residual_threshold_m": P(15.0, "float", "an aided fix whose largest normalised residual "
                                                 "(satellite or constraint, m referred to a weight-1 "
                                                 "satellite) exceeds this drops that satellite while still "
                                                 "over-determined, else is refused", lo=0.0),
    },
}


def default(dotted: str):
    """The schema default of navigation key ``dotted`` (e.g. ``"aiding.max_sats"``)."""
    node = SCHEMA
    for part in dotted.split("."):
        node = node[part]
    return node.default
