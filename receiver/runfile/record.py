"""The channel-epoch record: the one unit that flows from tracking to navigation and into HDF5.

One record is written per channel per integration epoch.  Epochs start on a code-period boundary of the
local replica: ``sample_index`` is the first sample of the epoch (counted from the first sample of the
file) and ``code_phase_chips`` the replica code phase at that sample (a small fraction of a chip, the
fractional-sample remainder).  The transmit time of that sample is therefore
``t_code_period_start + code_phase_chips / chip_rate``, which the navigation stage turns into
pseudoranges once frame sync has tied ``code_period`` to GPS time.
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
