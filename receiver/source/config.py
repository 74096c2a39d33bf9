"""The ``input`` section of the receiver config (schema fragment of the source stage) and its checks.

The format choices are the readers of :mod:`receiver.source.io` (``FORMATS``, then the GNSS-SDR / SigMF
``ALIASES``); receiver/schema.py assembles this fragment into the receiver's schema.
"""
from __future__ import annotations

from ..config import P, Section
from ..errors import UserError
from .io import ALIASES, BIT_ORDERS, ENCODINGS, FORMATS

#: the aliases of real (not complex) formats: input.if_hz must then lie in (0, fs/2)
REAL_FORMAT_ALIASES = tuple(a for a, f in ALIASES.items() if not FORMATS[f].complex)
FORMATS_ALL = tuple(FORMATS) + tuple(ALIASES)
#: signals whose file (input.signal_files) may have its own format and sample rate: they are read by their own
#: input stage (receiver.tracking.aided), not on the first signal's sample clock (acquisition.config.BAND_SIGNALS)
OWN_RATE_SIGNALS = ("gps_l5", "gal_e5a")

SCHEMA = {
    "path": P(None, "str", "IF sample file (relative paths are taken from the current directory; "
                          "`--input` overrides)", nullable=True),
    "format": P("int8_iq", "str", "sample format (docs: Your own recording; GNSS-SDR item_type and SigMF "
                                  "datatype names are accepted as aliases)",
                choices=tuple(FORMATS) + tuple(ALIASES)),
    "header_bytes": P(0, "int", "bytes skipped at the start of the file before the first sample", lo=0),
    "bit_order": P("msb_first", "str", "packed formats: the first field of a byte is in its most "
                                       "(msb_first) or least (lsb_first) significant bits",
                   choices=BIT_ORDERS),
    "encoding": P("sign_magnitude", "str", "packed1/2/4 formats: field encoding (sign_magnitude: "
                                           "top bit = sign, value +/-(2m+1); twos_complement: value 2s+1; "
                                           "offset_binary: value 2u-(2^bits-1))",
                  choices=ENCODINGS),
    "sample_rate_hz": P(2.6e6, "float", "sampling rate", lo=1e5),
    "if_hz": P(0.0, "float", "intermediate frequency (0 for complex baseband)"),
    "signal_files": P({}, "dict", "runs over several signals recorded into one file per signal at the same "
                                  "instant (one clock): signal name -> {path, if_hz, format, sample_rate_hz} "
                                  "of that signal's file (format and sample_rate_hz default to input.format "
                                  "and input.sample_rate_hz; gps_l5 and gal_e5a may have their own, e.g. 20.46 "
                                  "MS/s); a signal not listed is read from input.path, which holds the first signal"),
    "iq_swap": P(False, "bool", "swap I and Q (spectral inversion) on reading"),
    "decimate": P("auto", "any", "input stage: mix the IF to 0 Hz, low-pass filter and resample to a "
                                 "complex baseband stream before acquisition and tracking.  auto: when the "
                                 "input is at least 1.5x the target rate (4 MS/s for gps_l1ca, 8 MS/s for "
                                 "bds_b1i), resample to it by an exact ratio L/M (L, M <= 4096; else the "
                                 "largest whole factor, else the lowest whole rate above it that such a "
                                 "ratio reaches); slower inputs stay as they are, except a rate that is "
                                 "not a whole number of samples per ms (e.g. 2.0461 MS/s), which is "
                                 "resampled slightly up to one.  An integer N: decimate by N.  1: off "
                                 "(docs: Input conditioning)"),
    "skip_s": P(0.0, "float", "seconds skipped at the start of the file", lo=0.0),
    "duration_s": P(None, "float", "seconds processed (empty: to the end of the file)",
                    nullable=True, lo=0.0),
    "start_gps_week": P(None, "int", "GPS week of the first sample (only for assisted mode / "
                                     "time-tagging before the first decoded TOW)", nullable=True),
    "start_gps_tow_s": P(None, "float", "approximate GPS time of week of the first sample",
                         nullable=True),
    "conditioning": {
        "dc_removal": P(True, "bool", "remove the DC offset / LO leakage (a ~dc_bw_hz wide notch at 0 Hz "
                                      "that follows a drifting offset; not run when the decimating input "
                                      "stage mixes a nonzero IF down, which moves the DC to -IF)"),
        "tone_detection": P(True, "bool", "detect CW tones / spurs in the spectrum of the first detect_ms "
                                          "(reported in the run summary and /conditioning)"),
        "tone_excision": P(True, "bool", "cancel the detected tones (one adaptive notch of notch_bw_hz "
                                         "per tone, causal, continuous across blocks)"),
        "detect_ms": P(100.0, "float", "span analysed by the tone detector (ms; shorter files: all of "
                                       "it)", lo=1.0),
        "fft_size": P(4096, "int", "periodogram length of the tone detector (bin = sample rate / "
                                   "fft_size)", lo=64, hi=1 << 20),
        "pfa": P(1e-3, "float", "probability of one or more false tone detections over the whole "
                                "spectrum of white noise", lo=1e-12, hi=0.5),
        "min_db": P(6.0, "float", "a tone must also exceed the local noise floor of its periodogram "
                                   "bin by this much (dB)", lo=0.0),
        "max_tones": P(32, "int", "largest number of tones cancelled (the strongest; up to max(16, max_tones) are "
                                  "reported)", lo=0, hi=64),
        "notch_bw_hz": P(100.0, "float", "-3 dB width of each tone notch (Hz)", lo=1.0),
        "dc_bw_hz": P(100.0, "float", "-3 dB width of the DC notch (Hz)", lo=1.0),
        "pulse_blanking": P(False, "bool", "zero samples whose magnitude exceeds blank_sigma x the RMS "
                                           "of the conditioned detection span (pulsed interference)"),
        "blank_sigma": P(5.0, "float", "pulse blanking threshold in RMS units", lo=1.0),
        "pulse_detection": P(True, "bool", "detect pulsed interference (block powers far over a robust "
                                           "noise floor, repeated) in the detection span and at every "
                                           "monitor check, and blank the pulses while they last (docs: "
                                           "Field robustness); pulse_blanking selects the static blanker "
                                           "instead"),
        "pulse_threshold_db": P(6.0, "float", "pulse detector and blanker: power over the noise floor "
                                              "above which a block / the short-term power is a pulse (dB)",
                                lo=3.0),
        "tf_excision": P(True, "bool", "detect moving narrowband interference (swept / chirp jammers: "
                                       "short-time spectra with bins far over their floor in many frames "
                                       "and bins) in the detection span and at every monitor check, and "
                                       "excise it in short FFT frames while it lasts (docs: Field "
                                       "robustness)"),
        "tf_threshold_db": P(12.0, "float", "time-frequency excision: a frame's bin this far over its noise "
                                            "floor is zeroed (with its two neighbours; dB)", lo=6.0),
        "tf_frame_us": P(50.0, "float", "time-frequency excision frame length (us; rounded to a power of "
                                        "two samples)", lo=5.0, hi=2000.0),
        "pulse_min_count": P(3, "int", "separate pulses a detection / monitor span must hold for the "
                                       "blanker to switch on", lo=2),
        "monitor_ms": P(100.0, "float", "interference monitor: every monitor_ms of the stream the "
                                        "conditioned samples are checked for new tones (a notch is added "
                                        "at once) and every notch for a tone that has gone (removed); "
                                        "0: the tones of the first detect_ms only", lo=0.0),
        "notch_track_hz": P(3000.0, "float", "natural frequency of each tone notch's frequency-tracking "
                                             "loop (a drifting or swept tone stays in its notch); 0: fixed "
                                             "notch frequencies", lo=0.0),
        "monitor_segments": P(8, "int", "periodogram segments (of fft_size samples) per monitor check",
                              lo=2, hi=256),
        "monitor_false_per_hour": P(0.1, "float", "interference monitor: expected false tone detections "
                                                  "per hour of white noise (each check's false-alarm "
                                                  "probability is this x monitor_ms / 1 h, at most pfa; the "
                                                  "detection span keeps pfa)", lo=1e-9, hi=3600.0),
    },
}


def check(i: Section):
    """Checks of meaning across the input keys (one-line UserErrors): the IF inside the sampled band, the
    decimation factor."""
    half = i.sample_rate_hz / 2
    if i.format.endswith("_real") or i.format in REAL_FORMAT_ALIASES:
        if not 0.0 < i.if_hz < half:
            raise UserError(f"config key 'input.if_hz' must be in (0, sample_rate_hz/2 = {half:g}) for the "
                            f"real format {i.format}, got {i.if_hz:g}")
    elif abs(i.if_hz) >= half:
        raise UserError(f"config key 'input.if_hz' must be within +/- sample_rate_hz/2 = {half:g}, "
                        f"got {i.if_hz:g}")
    d = i.decimate
    if d != "auto" and (isinstance(d, bool) or not isinstance(d, int) or d < 1):
        raise UserError(f"config key 'input.decimate' must be auto or an integer >= 1, got {d!r}")


def _number(v) -> bool:
    return not isinstance(v, bool) and isinstance(v, (int, float))


def check_signal_files(i: Section, sigs: list):
    """input.signal_files names the run's signals after the first, each {path, if_hz[, format,
    sample_rate_hz]} with the IF inside the file's band; own formats and rates only for signals that read
    their file by themselves (OWN_RATE_SIGNALS)."""
    for name, v in (i.signal_files or {}).items():
        if name not in sigs[1:]:
            raise UserError(f"config key 'input.signal_files': {name!r} is not one of the run's signals after the "
                            f"first ({', '.join(sigs[1:]) or 'none'}; the first is read from input.path)")
        fs = v.get("sample_rate_hz", i.sample_rate_hz) if isinstance(v, dict) else i.sample_rate_hz
        if not isinstance(v, dict) or set(v) - {"path", "if_hz", "format", "sample_rate_hz"} or \
                not isinstance(v.get("path"), str) or not _number(v.get("if_hz", 0.0)) or not _number(fs) or \
                fs <= 0 or abs(v.get("if_hz", 0.0)) >= fs / 2 or v.get("format", i.format) not in FORMATS_ALL:
            raise UserError(f"config key 'input.signal_files.{name}' must be {{path: FILE, if_hz: HZ, format: F, "
                            f"sample_rate_hz: HZ}} (format, rate optional) with |if_hz| < sample_rate_hz/2, "
                            f"got {v!r}")
        own = ("format" in v and v["format"] != i.format) or fs != i.sample_rate_hz
        if own and name not in OWN_RATE_SIGNALS:
            raise UserError(f"config key 'input.signal_files.{name}': {name} is read on the first signal's "
                            f"sample clock: same format and sample_rate_hz as input.path (own ones: "
                            f"{', '.join(OWN_RATE_SIGNALS)})")
