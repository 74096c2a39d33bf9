"""The ``output`` section of the receiver config (schema fragment of the run file).

The compression choices are the writer's (:data:`receiver.runfile.writer.COMPRESSION`); receiver/schema.py
assembles this fragment into the receiver's schema.
"""
from __future__ import annotations

from ..config import P
from .writer import COMPRESSION

SCHEMA = {
    "path": P(None, "str", "HDF5 output (empty: <input stem>.h5 in the current directory; "
                           "`--output` overrides)", nullable=True),
    "report": P(False, "bool", "write a PNG report beside the HDF5 file (<stem>_report.png)"),
    "rinex": P(False, "bool", "write RINEX 3.04 observation and navigation files (<stem>.obs, <stem>.nav)"),
    "nmea": P(False, "bool", "write NMEA 0183 GGA/RMC/GSA/GSV sentences at the fix rate (<stem>.nmea)"),
    "kml": P(False, "bool", "write a KML track of the fixes (<stem>.kml)"),
    "gpx": P(False, "bool", "write a GPX track of the fixes (<stem>.gpx)"),
    "compression": P("gzip", "str", "compression of the growing run-file datasets (channels, navigation, "
                                     "observables, vector): gzip (level 4), lzf (faster, ~8 % larger) or "
                                     "none; both with the shuffle filter", choices=tuple(COMPRESSION)),
    "round_columns": P(True, "bool", "store the channel columns doppler_hz, code_rate_hz and "
                                     "code_phase_chips rounded to 1e-3 Hz, 1e-5 chip/s and 1e-7 chip "
                                     "(HDF5 scale-offset filter; far below their noise, docs: Run-file "
                                     "format); false: exact float64"),
    "channel_rate_hz": P(None, "float", "store the /channels records at most at this rate (the first epoch "
                                        "of every 1/rate interval; empty: every epoch).  Per-channel "
                                        "statistics (lock losses, locked epochs, mean C/N0) are computed "
                                        "over every epoch and stored as /channels/Gnn attributes",
                         nullable=True, lo=0.0),
    "vector_log_hz": P(100.0, "float", "rate of the vector-loop diagnostics in /vector (chi-square tags, "
                                       "state sigmas, each channel's R); 0 = not written", lo=0.0),
}
