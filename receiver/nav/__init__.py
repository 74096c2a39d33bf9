"""Navigation: broadcast ephemeris, RINEX navigation files, LNAV bits, atmosphere models, PVT."""
from .ephemeris import Ephemeris, IonoUtc, earth_rotation, sat_state, select
from .lnav import LnavDecoder, SubframeEvent, EphemerisEvent, IonoUtcEvent, encode_subframes, encode_frames
from .rinex import read_rinex_nav, write_rinex_nav
from .pvt import Fix, NavSolver, Observation

__all__ = ["Ephemeris", "IonoUtc", "earth_rotation", "sat_state", "select",
           "LnavDecoder", "SubframeEvent", "EphemerisEvent", "IonoUtcEvent", "encode_subframes",
           "encode_frames", "read_rinex_nav", "write_rinex_nav", "Fix", "NavSolver", "Observation"]
