"""gnssrx: a GNSS software receiver for recorded IF samples."""

__version__ = "0.1.0"
