"""The records of a run: the channel-epoch record (the one unit that flows from tracking to navigation and into
HDF5), the fix and observable rows of the navigation stage and the vector-loop log row.

One record is written per channel per integration epoch.  Epochs start on a code-period boundary of the
local replica: ``sample_index`` is the first sample of the epoch (counted from the first sample of the
file) and ``code_phase_chips`` the replica code phase at that sample (a small fraction of a chip, the
fractional-sample remainder).  The transmit time of that sample is therefore
``t_code_period_start + code_phase_chips / chip_rate``, which the navigation stage turns into
pseudoranges once frame sync has tied ``code_period`` to GPS time.

Galileo E1 channels (``gal_e1``, receiver.tracking.gal_channels) write the same record per 4-ms code period:
``code_period`` counts 4-ms periods, ``integration_ms`` is 4, ``prompt_i`` / ``prompt_q`` / ``early`` / ``late``
are the E1-C pilot's (CS25 wiped), ``prompt1_i`` / ``prompt1_q`` the E1-B (data) prompt -- one I/NAV symbol;
with the carrier locked on the pilot (transmitted as -e_C, ICD Eq. 11) a logic-0 symbol reads negative --,
``prompt2_*`` zero; ``state`` is pull-in, then bit_sync (every period is a symbol).
Their observables (OBS_DTYPE) and fixes are those of every signal; in a run over several signals Galileo PRN p
is satellite 300 + p (receiver.gnss.satid.sat_key) and its ephemerides are in ``/ephemeris_gal``.
"""
import numpy as np

EPOCH_DTYPE = np.dtype([
    ("time_s", "f8"),                # receiver time of sample_index since the first sample of the file
    ("sample_index", "i8"),          # first sample of the epoch
    ("code_period", "i8"),           # code periods since the channel started (epoch start)
    ("code_phase_chips", "f8"),      # replica code phase at sample_index (chips)
    ("code_rate_hz", "f8"),          # replica chip rate (chips/s)
    ("doppler_hz", "f8"),            # carrier NCO frequency minus IF
    ("carrier_phase_cycles", "f8"),  # accumulated carrier NCO phase at sample_index (cycles)
    ("prompt_i", "f4"),
    ("prompt_q", "f4"),
    ("early", "f4"),                 # |E|
    ("late", "f4"),                  # |L|
    ("cn0_dbhz", "f4"),
    ("pli", "f4"),                   # smoothed phase-lock indicator cos(2 phi)
    ("carrier_err_cycles", "f4"),    # carrier discriminator output
    ("code_err_chips", "f4"),        # code discriminator output
    ("pll_lock", "u1"),
    ("state", "u1"),                 # STATE_* below
    ("integration_ms", "u1"),
    ("prompt1_i", "f4"),             # prompt over the first / second half of the epoch
    ("prompt1_q", "f4"),             # (frequency discriminators: cross/dot of the halves)
    ("prompt2_i", "f4"),
    ("prompt2_q", "f4"),
])

STATE_PULL_IN = 0     # FLL-assisted pull-in
STATE_TRACK = 1       # PLL tracking, bit boundary unknown
STATE_BIT_SYNC = 2    # bit boundary known (epochs may be longer than 1 ms)
STATE_LOST = 3
STATE_NAMES = {STATE_PULL_IN: "pull_in", STATE_TRACK: "track", STATE_BIT_SYNC: "bit_sync",
               STATE_LOST: "lost"}

#: codes of an acquisition result's ``reason`` (why a PRN was not detected) in /acquisition/reason
ACQ_REASONS = {"": 0, "threshold": 1, "width": 2, "xcorr": 3, "verify": 4}

# ---- navigation and vector-loop rows (/navigation, /observables, /vector of the run file)
# fix mode: 0 scalar least squares; 1 vector loop with >= 4 channels carrying signal; 2 coast (vector filter
# propagated through an outage: fewer than 4 channels carry signal, n_sats = those that do); 3 aided (scalar
# least squares with the predicted clock bias/drift and height as extra measurements, navigation.aiding;
# n_sats = satellites measured, 3 or more)
MODE_NAMES = {0: "scalar", 1: "vector", 2: "coast", 3: "aided"}
MODE_AIDED = 3              # a scalar fix that used clock/height constraints (navigation.aiding)

FIX_DTYPE = np.dtype([
    ("gps_week", "i4"), ("gps_tow", "f8"), ("time_s", "f8"), ("ecef", "f8", (3,)),
    ("velocity_ecef", "f8", (3,)), ("clock_bias_m", "f8"), ("clock_drift_mps", "f8"),
    ("n_sats", "i4"), ("pdop", "f8"), ("hdop", "f8"), ("vdop", "f8"), ("gdop", "f8"),
    ("mode", "u1"),                 # MODE_NAMES: 0 scalar, 1 vector, 2 coast, 3 aided
    ("lat_deg", "f8"), ("lon_deg", "f8"), ("height_m", "f8"),
    ("iono_params", "u1"),          # IONO_PARAMS_NAMES: the Klobuchar set the fix's ionospheric correction used
])



def fix_row(out, fix, t_s: float, iono_code) -> tuple:
    """A FIX_DTYPE row: position, velocity and clock of ``out`` (a WLS fix or the PVT filter's output),
    satellites, DOPs and mode of the WLS ``fix`` (receiver.navigation.pvt.Fix), at receiver time t_s (s)."""
    from ..gnss.geodesy import ecef2lla
    lat, lon, h = ecef2lla(out.ecef)
    return (out.gps_week, out.gps_tow, t_s, out.ecef, out.velocity_ecef, out.clock_bias_m, out.clock_drift_mps,
            fix.n_sats, fix.pdop, fix.hdop, fix.vdop, fix.gdop, MODE_AIDED if fix.aiding else 0,
            float(lat), float(lon), float(h), iono_code)


# fix iono_params: 0 no ionospheric correction (navigation.ionosphere none, or no parameters known and
# navigation.klobuchar_fallback off); 1 broadcast parameters (decoded from the signal, or the RINEX navigation
# file's header in assisted mode); 2 the built-in fallback set (receiver/gnss/atmosphere.py), no broadcast
# parameters known yet.  Run files written before the column existed read back IONO_UNKNOWN.
IONO_NONE, IONO_BROADCAST, IONO_FALLBACK, IONO_UNKNOWN = 0, 1, 2, 255
IONO_PARAMS_NAMES = {IONO_NONE: "none", IONO_BROADCAST: "broadcast", IONO_FALLBACK: "fallback"}

OBS_DTYPE = np.dtype([
    ("epoch", "i4"), ("gps_week", "i4"), ("gps_tow", "f8"), ("time_s", "f8"), ("prn", "i4"),
    ("pseudorange_m", "f8"), ("pseudorange_rate_mps", "f8"), ("doppler_hz", "f8"),
    ("carrier_phase_cycles", "f8"), ("cn0_dbhz", "f4"), ("lock_time_s", "f4"),
    ("half_cycle_resolved", "u1"), ("used_in_fix", "u1"), ("elevation_deg", "f4"),
    ("azimuth_deg", "f4"), ("residual_m", "f4"),
])

#: vector-loop diagnostics (/vector), decimated to output.vector_log_hz; PRN-indexed columns (column prn-1)
#: are NaN for satellites without a vector channel
VECTOR_LOG_DTYPE = np.dtype([
    ("time_s", "f8"), ("tag_code", "f4"), ("tag_carrier", "f4"), ("manoeuvre", "u1"), ("n_valid", "u1"),
    ("n_lock", "u1"), ("sigma_pos_m", "f4", (3,)), ("sigma_vel_mps", "f4", (3,)), ("sigma_bias_m", "f4"),
    ("sigma_drift_mps", "f4"), ("r_code_m2", "f4", (32,)), ("r_carrier_m2s2", "f4", (32,)),
    ("isb_m", "f4", (2,)), ("sigma_isb_m", "f4", (2,)),     # inter-system bias of BeiDou, Galileo (NaN: none)
])
#: the systems of VECTOR_LOG_DTYPE's isb_m / sigma_isb_m columns
VECTOR_ISB_SYSTEMS = ("C", "E")
