"""Typed, validated YAML configuration.

A schema is a nested dict whose leaves are :class:`P` (parameter specs with a default, a type, a
documentation string and optional limits).  :func:`build` merges a user's YAML (and ``--set`` overrides)
over the defaults and returns a :class:`Section` tree with attribute access.  Unknown keys, wrong types and
out-of-range values raise :class:`receiver.errors.UserError` naming the dotted key.

The receiver's own schema is :data:`RECEIVER_SCHEMA`; other commands (simulator scenarios, LEO, batch)
define their own schemas with the same machinery.
"""
from __future__ import annotations

import copy
import math
import os
import re
from dataclasses import dataclass, field
from typing import Any

import yaml

from .errors import UserError
from .suggest import did_you_mean, refuse_binary

#: YAML dumper of Section.to_yaml: the safe dumper, through libyaml when PyYAML was built with it
_SAFE_DUMPER = getattr(yaml, "CSafeDumper", yaml.SafeDumper)

_REQUIRED = object()


@dataclass
class P:
    """One parameter: default value, type name, doc string and limits.

    kind: float | int | bool | str | list_int | list_float | list | dict | any
    """
    default: Any
    kind: str
    doc: str
    choices: tuple | None = None
    lo: float | None = None
    hi: float | None = None
    nullable: bool = False
    required: bool = False
    extra: dict = field(default_factory=dict)


class Section:
    """Attribute-access view of one config level."""

    def __init__(self, values: dict):
        self.__dict__["_values"] = values

    def __getattr__(self, name):
        try:
            return self._values[name]
        except KeyError:
            raise AttributeError(name) from None

    def __setattr__(self, name, value):
        raise AttributeError("config sections are read-only")

    def __getitem__(self, name):
        return self._values[name]

    def __contains__(self, name):
        return name in self._values

    def get(self, dotted: str):
        node = self
        for part in dotted.split("."):
            node = node[part]
        return node

    def to_dict(self) -> dict:
        return {k: (v.to_dict() if isinstance(v, Section) else copy.deepcopy(v))
                for k, v in self._values.items()}

    def to_yaml(self) -> str:
        """The section as YAML (libyaml's emitter when PyYAML has it: ~4x faster than the pure-Python one,
        the same text for every shipped config, tests/unit/core/test_config_yaml_dump.py)."""
        return yaml.dump(self.to_dict(), Dumper=_SAFE_DUMPER, sort_keys=False)

    def __repr__(self):
        return f"Section({self.to_dict()!r})"


def _check(key: str, spec: P, value):
    if value is None:
        if spec.nullable:
            return None
        raise UserError(f"config key '{key}' must not be empty")
    k = spec.kind
    try:
        if k == "float":
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise TypeError
            value = float(value)
            if not math.isfinite(value):
                raise ValueError
        elif k == "int":
            if isinstance(value, bool) or not (isinstance(value, int) or
                                               (isinstance(value, float) and value.is_integer())):
                raise TypeError
            value = int(value)
        elif k == "bool":
            if not isinstance(value, bool):
                raise TypeError
        elif k == "str":
            if not isinstance(value, str):
                raise TypeError
        elif k in ("list_int", "list_float"):
            if isinstance(value, (int, float)) and not isinstance(value, bool):
                value = [value]
            if not isinstance(value, list):
                raise TypeError
            sub = P(None, k[5:], spec.doc)
            value = [_check(f"{key}[{i}]", sub, v) for i, v in enumerate(value)]
        elif k == "list":
            if not isinstance(value, list):
                raise TypeError
        elif k == "dict":
            if not isinstance(value, dict):
                raise TypeError
        elif k != "any":
            raise AssertionError(f"unknown kind {k}")
    except (TypeError, ValueError):
        raise UserError(f"config key '{key}' must be of type {k}, got {value!r}") from None
    if spec.choices is not None and value not in spec.choices:
        raise UserError(f"config key '{key}' must be one of {', '.join(map(str, spec.choices))}; "
                        f"got {value!r}" + did_you_mean(value, spec.choices))
    for v in (value if isinstance(value, list) and k.startswith("list_") else [value]):
        if spec.lo is not None and v < spec.lo:
            raise UserError(f"config key '{key}' must be >= {spec.lo}, got {v!r}")
        if spec.hi is not None and v > spec.hi:
            raise UserError(f"config key '{key}' must be <= {spec.hi}, got {v!r}")
    return value


def _merge(schema: dict, user: dict, prefix: str) -> dict:
    if not isinstance(user, dict):
        raise UserError(f"config section '{prefix.rstrip('.') or '<top>'}' must be a mapping")
    unknown = [k for k in user if k not in schema]
    if unknown:
        raise UserError(f"unknown config key '{prefix}{unknown[0]}'" + did_you_mean(unknown[0], schema, prefix))
    out = {}
    for name, spec in schema.items():
        key = prefix + name
        if isinstance(spec, dict):
            out[name] = Section(_merge(spec, user.get(name) or {}, key + "."))
        else:
            if name in user:
                out[name] = _check(key, spec, user[name])
            elif spec.required:
                raise UserError(f"config key '{key}' is required")
            else:
                out[name] = copy.deepcopy(spec.default)
    return out


class YamlLoader(yaml.SafeLoader):
    """SafeLoader that also reads exponent floats without a dot (1e-3, 2e-19) as floats, as YAML 1.2 does;
    PyYAML (YAML 1.1) would read them as strings."""


YamlLoader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"^[-+]?(?:[0-9][0-9_]*)(?:\.[0-9_]*)?[eE][-+]?[0-9]+$"),
    list("-+0123456789"))


def yaml_load(stream):
    """yaml.safe_load with :class:`YamlLoader` (every config, scenario and batch file goes through it)."""
    return yaml.load(stream, Loader=YamlLoader)


def parse_override(item: str) -> tuple[str, Any]:
    """Parse one ``--set dotted.key=value`` (value parsed as YAML)."""
    if "=" not in item:
        raise UserError(f"--set expects dotted.key=value, got '{item}'")
    key, text = item.split("=", 1)
    try:
        value = yaml_load(text) if text.strip() else None
    except yaml.YAMLError:
        value = text
    return key.strip(), value


def apply_overrides(raw: dict, overrides) -> dict:
    raw = copy.deepcopy(raw)
    for item in overrides or ():
        key, value = parse_override(item) if isinstance(item, str) else item
        node = raw
        parts = key.split(".")
        for part in parts[:-1]:
            nxt = node.get(part)
            if nxt is None:
                nxt = node[part] = {}
            if not isinstance(nxt, dict):
                raise UserError(f"--set {key}: '{part}' is not a section")
            node = nxt
        node[parts[-1]] = value
    return raw


def read_utf8(path, what: str = "file") -> str:
    """The text of a UTF-8 file; another encoding (or binary data) is a one-line UserError naming the
    first bad byte and its line."""
    path = os.fspath(path)
    refuse_binary(path, what)                   # a recording given as the config: say so
    try:
        with open(path, "rb") as fh:
            data = fh.read()
    except OSError as exc:
        raise UserError(f"cannot read {what} {path}: {exc.strerror or exc}") from None
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = data.count(b"\n", 0, exc.start) + 1
        raise UserError(f"{what} {path} is not UTF-8 text (byte 0x{data[exc.start]:02x} on line {line}); "
                        f"save it as UTF-8") from None


def read_yaml(path) -> dict:
    """Read a YAML mapping; errors become one-line UserErrors."""
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise UserError(f"config file not found: {path}")
    text = read_utf8(path, "config file")
    try:
        raw = yaml_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" (line {mark.line + 1})" if mark else ""
        raise UserError(f"config file {path} is not valid YAML{where}") from None
    if raw is None:
        raw = {}
    if not isinstance(raw, dict):
        raise UserError(f"config file {path} must hold a YAML mapping")
    return raw


def build(schema: dict, raw: dict | None = None, overrides=None) -> Section:
    """Validate raw (already parsed YAML) plus overrides against schema."""
    return Section(_merge(schema, apply_overrides(raw or {}, overrides), ""))


def defaults_doc(schema: dict, prefix: str = "") -> list[tuple[str, str, Any, str]]:
    """(key, kind, default, doc) rows, for the configuration reference (docs/reference/config.md)."""
    rows = []
    for name, spec in schema.items():
        if isinstance(spec, dict):
            rows += defaults_doc(spec, prefix + name + ".")
        else:
            kind = spec.kind + (f" ({'|'.join(map(str, spec.choices))})" if spec.choices else "")
            rows.append((prefix + name, kind, spec.default, spec.doc))
    return rows


# --------------------------------------------------------------------------------------------------
# The receiver's schema
# --------------------------------------------------------------------------------------------------
# the formats of receiver/source/io.py (FORMATS), then the GNSS-SDR / SigMF aliases (ALIASES);
# tests/unit/core/test_registries.py checks both
INPUT_FORMATS = ("int8_iq", "int16_iq", "uint8_iq", "complex64", "float32_real", "int8_real", "int16_real",
                 "int4_iq", "packed1_real", "packed1_iq", "packed2_real", "packed2_iq", "packed4_real", "packed4_iq")
INPUT_FORMAT_ALIASES = ("gr_complex", "cshort", "ishort", "cbyte", "ibyte", "byte", "short", "float",
                        "cf32_le", "ci16_le", "ci8", "cu8", "rf32_le", "ri16_le", "ri8")
REAL_FORMAT_ALIASES = ("byte", "short", "float", "rf32_le", "ri16_le", "ri8")
#: the signal names of receiver.gnss.registry (a lower layer may not import it; tests/unit/core/test_registries.py)
SIGNAL_CHOICES = ("gps_l1ca", "bds_b1i", "gal_e1")
CARRIER_VARIANTS = ("pll", "cpll_atan", "ekf", "pli_ekf", "kf", "adaptive_kf")

RECEIVER_SCHEMA = {
    "input": {
        "path": P(None, "str", "IF sample file (relative paths are taken from the current directory; "
                              "`--input` overrides)", nullable=True),
        "format": P("int8_iq", "str", "sample format (docs: Your own recording; GNSS-SDR item_type and SigMF "
                                      "datatype names are accepted as aliases)",
                    choices=INPUT_FORMATS + INPUT_FORMAT_ALIASES),
        "header_bytes": P(0, "int", "bytes skipped at the start of the file before the first sample", lo=0),
        "bit_order": P("msb_first", "str", "packed formats: the first field of a byte is in its most "
                                           "(msb_first) or least (lsb_first) significant bits",
                       choices=("msb_first", "lsb_first")),
        "encoding": P("sign_magnitude", "str", "packed1/2/4 formats: field encoding (sign_magnitude: "
                                               "top bit = sign, value +/-(2m+1); twos_complement: value 2s+1; "
                                               "offset_binary: value 2u-(2^bits-1))",
                      choices=("sign_magnitude", "twos_complement", "offset_binary")),
        "sample_rate_hz": P(2.6e6, "float", "sampling rate", lo=1e5),
        "if_hz": P(0.0, "float", "intermediate frequency (0 for complex baseband)"),
        "signal_files": P({}, "dict", "runs over several signals recorded into one file per signal at the same "
                                      "instant: signal name -> {path, if_hz} of that signal's file (same format "
                                      "and sample rate as input.path, which holds the first signal); a signal "
                                      "not listed is read from input.path"),
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
            "monitor_ms": P(100.0, "float", "interference monitor: every monitor_ms of the stream the "
                                            "conditioned samples are checked for new tones (a notch is added "
                                            "at once) and every notch for a tone that has gone (removed); "
                                            "0: the tones of the first detect_ms only", lo=0.0),
            "notch_track_hz": P(3000.0, "float", "natural frequency of each tone notch's frequency-tracking "
                                                 "loop (a drifting or swept tone stays in its notch); 0: fixed "
                                                 "notch frequencies", lo=0.0),
            "monitor_segments": P(8, "int", "periodogram segments (of fft_size samples) per monitor check",
                                  lo=2, hi=256),
        },
    },
    "signal": P("gps_l1ca", "str", "signal to acquire, track and navigate with: gps_l1ca (GPS and QZSS "
                                   "L1 C/A, LNAV) or bds_b1i (BeiDou B1I, D1/D2 messages); gal_e1 (Galileo E1 OS) "
                                   "is defined (codes, I/NAV) but not yet acquired or tracked",
                choices=SIGNAL_CHOICES),
    "signals": P([], "list", "several signals in one run (e.g. [gps_l1ca, bds_b1i]; empty: `signal` alone): "
                             "every signal is acquired and tracked from the same input (input.if_hz is the IF "
                             "of the first; the others sit at if_hz + their carrier - the first's), and the "
                             "fixes use all systems with an inter-system clock bias (docs: BeiDou and multi-GNSS)"),
    "acquisition": {
        "prns": P(list(range(1, 33)), "list_int", "PRNs searched (gps_l1ca: GPS 1-32 and QZSS 193-202 = "
                                                  "J01-J10; bds_b1i: 1-63)", lo=1, hi=202),
        "prns_by_signal": P({}, "dict", "runs over several signals: PRNs searched per signal name (e.g. "
                                        "{bds_b1i: [6, 7, 8]}); a signal not listed searches acquisition.prns "
                                        "when it is the first of `signals`, else all its PRNs"),
        "coherent_ms": P(4, "int", "coherent integration per non-coherent step (ms)", lo=1, hi=10),
        "noncoherent": P(10, "int", "number of non-coherent sums", lo=1, hi=100),
        "doppler_max_hz": P(10000.0, "float", "Doppler search half-range", lo=0.0),
        "doppler_step_hz": P(None, "float", "Doppler bin width (empty: 1/(2 T_coh))", nullable=True,
                             lo=1.0),
        "pfa": P(1e-3, "float", "false-alarm probability over one PRN's search grid", lo=1e-12, hi=0.5),
        "threshold": P(1.25, "float", "factor on the pfa-derived detection threshold: margin for the "
                                      "non-Gaussian tail that strong signals' cross-correlation adds (docs: Acquisition)",
                       lo=0.1),
        "start_s": P(0.0, "float", "time into the processed span where acquisition starts", lo=0.0),
        "width_ratio": P(0.3, "float", "a peak is rejected when the mean power 2-4 chips beside it, above "
                                       "the floor, exceeds this fraction of the peak's (CW tones give broad "
                                       "maxima)", lo=0.0),
        "verify": P(True, "bool", "verification dwell: a detection must be found again in the next, "
                                  "independent coherent_ms x noncoherent block (skipped when the file is "
                                  "too short)"),
        "lo_search_hz": P(25000.0, "float", "when fewer than 4 satellites are found, search the others again "
                                            "over this Doppler half-range (front-end LO offsets; 0 = off)",
                          lo=0.0),
        "lo_warn_hz": P(3000.0, "float", "warn when the median Doppler of the satellites found exceeds "
                                         "this (a common LO / oscillator offset)", lo=0.0),
        "high_sensitivity": {
            "enabled": P(True, "bool", "when the fast search finds fewer than min_found satellites, search "
                                       "the others again with the high-sensitivity pass (receiver/"
                                       "acquisition_hs.py: 10-ms blocks, alternate half-bit sums, code Doppler "
                                       "compensated, Doppler range narrowed by the satellites found)"),
            "min_found": P(6, "int", "run the high-sensitivity pass when the fast search finds fewer "
                                     "satellites than this", lo=1, hi=32),
            "coherent_ms": P(10, "int", "coherent block (ms; divides 20: a data bit holds whole blocks)",
                             choices=(1, 2, 4, 5, 10)),
            "noncoherent": P(20, "int", "blocks summed non-coherently (the verification dwell is another as "
                                        "many)", lo=2, hi=200),
            "pfa": P(1e-3, "float", "false-alarm probability over one PRN's search grid", lo=1e-12, hi=0.5),
            "sat_doppler_hz": P(5000.0, "float", "bound of a satellite's own Doppler (line of sight, plus the "
                                                 "receiver's motion): the satellites found bound the common "
                                                 "oscillator offset and narrow the search", lo=0.0),
            "cold": P(True, "bool", "the periodic cold searches of missing satellites use this pass too while "
                                    "fewer than min_found channels track"),
        },
    },
    "tracking": {
        "max_channels": P(12, "int", "maximum number of tracking channels", lo=1, hi=64),
        "integration_ms": P(1, "int", "coherent integration after bit sync (1, 2, 4, 5, 10, 20 ms)",
                            choices=(1, 2, 4, 5, 10, 20)),
        "pull_in_ms": P(300, "int", "duration of FLL-assisted pull-in (ms)", lo=0),
        "fll_bw_hz": P(1.0, "float", "FLL noise bandwidth during pull-in (1st-order FLL aiding a 2nd-order "
                                      "PLL; wider FLLs random-walk at low C/N0)", lo=0.0),
        "pll_bw_hz": P(25.0, "float", "PLL noise bandwidth", lo=0.1),
        "pll_order": P(3, "int", "PLL order", choices=(2, 3)),
        "dll_bw_hz": P(2.0, "float", "DLL noise bandwidth (carrier aided)", lo=0.01),
        "dll_order": P(2, "int", "DLL order (2 absorbs a code/carrier rate mismatch)", choices=(1, 2)),
        "dll_bw_pull_in_hz": P(4.0, "float", "DLL noise bandwidth during pull-in", lo=0.01),
        "early_late_chips": P(0.5, "float", "early-late spacing (total, chips)", lo=0.05, hi=1.5),
        "early_late_snap": P(False, "bool", "round the early/late offsets to whole samples on every channel "
                                            "(0.5 chip becomes 0.79 chip at 2.6 MS/s: 1.8x the 3D RMS on the "
                                            "third-party recording); off: whole samples only while a channel "
                                            "pulls in and on weak channels, the exact spacing otherwise "
                                            "(docs: Tracking)"),
        "cn0_window_ms": P(200, "int", "window for the C/N0 estimator (ms)", lo=20),
        "cn0_estimator": P("snv", "str", "C/N0 estimator: snv (signal-to-noise variance of the locked "
                                         "prompt; M2M4 before lock) or m2m4", choices=("snv", "m2m4")),
        "lock_cn0_min_dbhz": P(25.0, "float", "C/N0 below which lock is declared lost", lo=0.0),
        "lock_ratio_min": P(1.5, "float", "PLL lock detector: lock while low-passed |I| exceeds this "
                                          "times low-passed |Q|", lo=1.0),
        "lost_ms": P(200, "int", "time below the lock thresholds before a channel declares the signal lost "
                                "(its satellite is then re-acquired around the prediction; docs: Tracking, signal outages)",
                     lo=10),
        "lost_grace_ms": P(1000, "int", "a channel is declared lost only after this long below the lock "
                                        "thresholds while it is younger than this (since its pull-in began): a "
                                        "weak signal needs time to reach phase lock", lo=0),
        "presence": {
            "window_ms": P(20, "int", "signal-presence test: the prompt power over windows of this length is "
                                      "compared with its level while the signal was present; a vanished "
                                      "signal is seen within 1-2 windows (the lock detectors and the C/N0 "
                                      "window lag it by 0.15-0.4 s); 0 = off", lo=0),
            "drop_db": P(10.0, "float", "the signal is absent when the window power falls this far below its "
                                        "level while present", lo=1.0),
            "min_cn0_dbhz": P(30.0, "float", "only a channel with at least this C/N0 can be declared absent by "
                                             "the test (weaker signals: the lock detectors alone; a fade of a "
                                             "weak signal must not read as a loss)", lo=0.0),
            "lost_ms": P(40, "int", "absent this long: the channel declares the signal lost (then re-acquired "
                                    "around the prediction); meanwhile it has no lock and C/N0 0, so no "
                                    "measurement of it enters a fix (scalar or vector)", lo=1),
        },
        "reacquire_s": P(5.0, "float", "interval between cold re-acquisition attempts for PRNs never tracked "
                                       "or no longer predictable", lo=0.1),
        "weak": {
            "enabled": P(True, "bool", "weak-signal tracking: a channel whose C/N0 estimates stay below "
                                       "cn0_dbhz during the first second after its pull-in is weak (latched "
                                       "until it is lost); a channel that starts strong keeps the thresholds "
                                       "above (signal outages are detected as fast)"),
            "cn0_dbhz": P(32.0, "float", "C/N0 below which a starting channel is weak (the acquisition's "
                                         "estimate opens a channel weak at once)", lo=0.0, hi=60.0),
            "integration_ms": P(20, "int", "coherent integration of a weak channel after bit sync",
                                choices=(1, 2, 4, 5, 10, 20)),
            "pll_bw_hz": P(10.0, "float", "PLL noise bandwidth of a weak channel (built-in loop; B T <= 0.2 "
                                          "at 20 ms)", lo=0.1),
            "dll_bw_hz": P(0.5, "float", "DLL noise bandwidth of a weak channel (carrier aided: the code noise, "
                                         "not the dynamics, sets it)", lo=0.01),
            "fll_bw_hz": P(0.0, "float", "FLL noise bandwidth of a weak channel's pull-in (the 1-ms frequency "
                                         "discriminator is noise below ~30 dB-Hz; 0: the PLL alone, started "
                                         "from the acquisition's fine Doppler)", lo=0.0),
            "lost_grace_ms": P(3000, "int", "lost-grace time of a young weak channel (tracking.lost_grace_ms "
                                            "for the others)", lo=0),
            "lock_ratio_min": P(1.25, "float", "lock ratio of a weak channel (low-passed |I| / |Q|)", lo=1.0),
            "lock_window_ms": P(200.0, "float", "low-pass time constant of a weak channel's lock detector (ms)",
                                lo=1.0),
            "lock_cn0_min_dbhz": P(20.0, "float", "C/N0 below which a weak channel's lock is lost", lo=0.0),
            "bit_sync_ms": P(1000, "int", "bit sync by the energy of 20-ms prompt sums per edge hypothesis "
                                          "after this many ms when the sign-change histogram has not decided "
                                          "(0: off)", lo=0),
            "dll_hold_ms": P(2000, "int", "a weak channel's DLL keeps tracking.dll_bw_pull_in_hz this long "
                                          "after its pull-in (the pull-in's code error converges at the "
                                          "normal rate; its rate integrator at dll_bw_hz throughout), then "
                                          "narrows to dll_bw_hz", lo=0),
            "exit_cn0_dbhz": P(35.0, "float", "a weak channel whose C/N0 estimates reach this in 3 windows in a "
                                              "row (tracking.cn0_window_ms each) while locked is handed over to "
                                              "the normal loops (the acquisition's estimate reads up to ~3 dB "
                                              "low; 0: weak until lost)", lo=0.0, hi=60.0),
        },
        "reacquisition": {
            "doppler_hz": P(40.0, "float", "Doppler half-window of the hot search right after a loss (error of "
                                           "the Doppler extrapolated from the last tracked state)", lo=0.0),
            "code_chips": P(1.5, "float", "code-phase half-window of the hot search right after a loss",
                            lo=0.0),
            "accel_mps2": P(5.0, "float", "receiver acceleration bound along the line of sight: the windows "
                                          "widen by accel t / lambda (Doppler) and accel t^2 / 2 (code) with "
                                          "the outage length t (warm start)", lo=0.0),
            "speed_mps": P(60.0, "float", "receiver speed bound: caps the widening at 2 speed / lambda "
                                          "(Doppler) and 2 speed t (code)", lo=0.0),
            "max_age_s": P(300.0, "float", "outages longer than this fall back to the cold full-grid search",
                           lo=0.0),
            "coherent_ms": P(2, "int", "coherent integration of the narrow search (ms)", lo=1, hi=10),
            "noncoherent": P(10, "int", "non-coherent sums of the narrow search", lo=1, hi=100),
            "pfa": P(1e-4, "float", "false-alarm probability over the narrow search window", lo=1e-12,
                     hi=0.5),
            "pull_in_ms": P(40, "int", "FLL-assisted pull-in of a re-acquired channel (ms)", lo=0),
            "dll_bw_pull_in_hz": P(15.0, "float", "DLL noise bandwidth during a re-acquired channel's pull-in "
                                                 "(1st order: the code error left by the narrow search decays "
                                                 "with time constant 1 / (4 B))", lo=0.01),
            "settle_s": P(0.1, "float", "a re-acquired channel's measurements are used this long after its "
                                        "pull-in", lo=0.0),
            "settle_predicted_s": P(0.02, "float", "the same for a hot re-acquisition whose code phase was "
                                                   "predicted to better than 0.05 chip and found by the search "
                                                   "within 0.5 chip of the prediction (the channel starts on the "
                                                   "prediction: no DLL transient to wait for)", lo=0.0),
            "search_step_s": P(0.125, "float", "narrow searches run at this step through each chunk just tracked "
                                               "(a returning satellite is found within a step, not a chunk); "
                                               "0: once per chunk, at its end", lo=0.0),
            "search_after_s": P(0.15, "float", "narrow searches start this long after the last good epoch "
                                               "of a lost satellite", lo=0.0),
        },
        "carrier": {
            "variant": P("pll", "str", "carrier loop variant: pll (built-in FLL-assisted PLL), cpll_atan "
                                       "(ATAN Costas PLL, loop filter of order `order`), ekf (I/Q extended "
                                       "Kalman filter), pli_ekf (EKF with PLI-weighted observation), kf "
                                       "(Kalman-filter PLL on the ATAN discriminator), adaptive_kf (kf with "
                                       "innovation-scaled Q and NWPR-C/N0 R); auto: chosen per channel when it "
                                       "opens, by the acquisition's C/N0 estimate (auto_weak below "
                                       "tracking.weak.cn0_dbhz, auto_strong otherwise)",
                         choices=CARRIER_VARIANTS + ("auto",)),
            "auto_weak": P("adaptive_kf", "str", "variant auto: the loop of a channel the acquisition estimates "
                                                 "below tracking.weak.cn0_dbhz", choices=CARRIER_VARIANTS),
            "auto_strong": P("pll", "str", "variant auto: the loop of the other channels",
                             choices=CARRIER_VARIANTS),
            "t_coh_ms": P(None, "int", "coherent integration of the carrier loop after bit sync (empty: "
                                       "tracking.integration_ms); limited to the data-symbol length unless "
                                       "dataless", nullable=True, choices=(1, 2, 4, 5, 10, 20)),
            "dataless": P(False, "bool", "the signal carries no data symbols (simulator navigation.data: "
                                         "false): integrate across symbol edges; overlay codes still apply"),
            "bn_hz": P(15.0, "float", "cpll_atan: loop noise bandwidth", lo=0.1),
            "order": P(3, "int", "cpll_atan: loop order", choices=(2, 3)),
            "clock_h0": P(2e-19, "float", "kf/ekf process noise: oscillator white FM level h0", lo=0.0),
            "clock_h_2": P(2e-20, "float", "kf/ekf process noise: oscillator random-walk FM level h_-2",
                           lo=0.0),
            "kf": {
                "cn0_dbhz": P(35.0, "float", "kf: design C/N0 for the discriminator variance R", lo=0.0),
                "jerk_psd": P(4.0, "float", "kf: PSD of the white line-of-sight jerk ((m/s^3)^2/Hz)",
                              lo=0.0),
                "window": P(20, "int", "adaptive_kf: innovation window m (epochs)", lo=2),
                "cn0_tau_s": P(0.5, "float", "adaptive_kf: NWPR C/N0 smoothing time constant", lo=0.0),
            },
            "ekf": {
                "bn_hz": P(15.0, "float", "ekf/pli_ekf: loop bandwidth at the design C/N0 (sets the "
                                          "white-snap process noise)", lo=0.1),
                "cn0_dbhz": P(40.0, "float", "ekf/pli_ekf: design C/N0 for bn_hz", lo=0.0),
                "amp_tau_s": P(0.05, "float", "ekf/pli_ekf: smoothing of the amplitude / noise power "
                                              "estimates", lo=0.0),
                "cn0_tau_s": P(0.5, "float", "ekf/pli_ekf: NWPR C/N0 smoothing time constant", lo=0.0),
                "pli_tau_s": P(0.1, "float", "pli_ekf: low-pass time constant of I^2, Q^2 in the PLI "
                                             "(0: the epoch's own I, Q)", lo=0.0),
                "pli_min": P(0.0, "float", "pli_ekf: the PLI weight is clipped to [pli_min, 1] (0: ours, a "
                                           "weight; -1: the paper's unclipped PLI = cos 2 phi)", lo=-1.0, hi=1.0),
            },
        },
    },
    "navigation": {
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
        "weighting": P("elevation", "str", "WLS weights: sin^2(el), C/N0, none, or rtklib (RTKLIB's default "
                                               "single-point error model, to compare with rnx2rtkp)",
                       choices=("elevation", "cn0", "none", "rtklib")),
        "residual_threshold_m": P(30.0, "float", "drop the worst satellite when a residual exceeds this",
                                  lo=0.0),
        "max_pdop": P(20.0, "float", "no fix when the PDOP of the satellites used exceeds this (4-satellite "
                                     "fixes in urban canyons reach PDOP > 100 and errors of hundreds of m)",
                      lo=1.0),
        "filter": P("wls", "str", "navigation solution: wls (single-epoch weighted least squares and "
                                  "Doppler velocity), ekf (extended Kalman filter) or ckf (square-root "
                                  "cubature Kalman filter) over position, velocity, clock bias and drift, fed "
                                  "with the pseudoranges and pseudorange rates of the satellites the WLS fix "
                                  "used; /navigation then holds the filtered position, velocity and clock "
                                  "(n_sats, DOPs and /observables stay the WLS's; receiver/navigation/pvt_filter.py)",
                    choices=("wls", "ekf", "ckf")),
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
                          choices=("tcxo", "ocxo", "rubidium")),
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
                                    "(DLL/PLL transients over)", lo=0.0),
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
    },
    "vector": {
        "enabled": P(False, "bool", "hand scalar channels over to a vector loop (gps_l1ca incl. QZSS, "
                                    "bds_b1i, or both: one inter-system bias per extra system)"),
        "variant": P("adaptive_r", "str", "vector loop variant",
                     choices=("fixed_r", "adaptive_r", "polynomial", "cv")),
        "start_s": P(None, "float", "handover time in seconds from the first sample (empty: 5 s after "
                                    "the first valid fix)", nullable=True, lo=0.0),
        "integration_ms": P(1, "int", "vector-loop epoch T = coherent integration (ms; > 1 only on "
                                      "bit-synchronised channels, the others average 1 ms epochs; at most "
                                      "10 ms: an epoch must fit in the pipeline's 30 ms chunk overlap)",
                            choices=(1, 2, 4, 5, 10)),
        "r_code_m2": P(1500.0, "float", "code discriminator variance R (m^2; fixed_r, cv, initial value of "
                                        "the adaptive variants)", lo=1e-6),
        "r_carrier_m2s2": P(900.0, "float", "frequency discriminator variance R ((m/s)^2)", lo=1e-6),
        "r_model": P("fixed", "str", "measurement noise R of the discriminators: fixed = r_code_m2 / "
                                     "r_carrier_m2s2 for every channel (the papers'); cn0 = per channel from its "
                                     "C/N0 estimate and integration time (vector.r_cn0; the adaptive variants "
                                     "start from it)", choices=("fixed", "cn0")),
        "r_cn0": {
            "min_cn0_dbhz": P(22.0, "float", "r_model cn0: C/N0 used for R never below this (an estimate on "
                                             "noise alone reads 20-30 dB-Hz)", lo=0.0),
            "floor_code_m2": P(4.0, "float", "r_model cn0: lower limit of the code R (m^2)", lo=1e-9),
            "floor_carrier_m2s2": P(0.05, "float", "r_model cn0: lower limit of the frequency R ((m/s)^2)",
                                    lo=1e-9),
            "scale": P(1.0, "float", "r_model cn0: factor on both theoretical variances", lo=1e-6),
        },
        "motion_model": P("cv", "str", "fixed_r/adaptive_r kinematic model: cv = constant velocity (the "
                                       "papers' 8 states), ca = constant acceleration (3 more states)",
                          choices=("cv", "ca")),
        "q_accel": P(10.0, "float", "fixed_r/adaptive_r, motion_model cv: PSD of the white receiver "
                                    "acceleration per axis (m^2/s^3)", lo=0.0),
        "q_jerk": P(1.0, "float", "fixed_r/adaptive_r, motion_model ca: PSD of the white receiver jerk per "
                                  "axis (m^2/s^5)", lo=0.0),
        "q_vertical_scale": P(1.0, "float", "fixed_r/adaptive_r: factor on the kinematic PSD along the local "
                                            "vertical (at handover); 1 = isotropic, a land vehicle ~0.001",
                              lo=0.0),
        "init_sigma_acc_mps2": P(2.0, "float", "motion_model ca: initial acceleration standard deviation "
                                               "(m/s^2; the acceleration starts at zero)", lo=0.0),
        "clock_class": P("tcxo", "str", "oscillator class of the clock process noise (h0, h_-2)",
                         choices=("tcxo", "ocxo", "rubidium")),
        "code_carrier_drift": P(True, "bool", "estimate a code-minus-carrier clock drift state (front ends "
                                              "whose oscillator error reaches the carrier only; ionospheric "
                                              "divergence)"),
        "q_code_carrier_drift": P(1e-4, "float", "PSD of the code-minus-carrier drift random walk "
                                                 "((m/s)^2/s)", lo=0.0),
        "init_sigma_pos_m": P(10.0, "float", "initial position standard deviation at handover", lo=0.0),
        "init_sigma_vel_mps": P(1.0, "float", "initial velocity standard deviation at handover", lo=0.0),
        "cn0_mask_dbhz": P(None, "float", "channels below this C/N0 are predicted only (no measurement "
                                          "update); empty: every channel updates (the papers' setting)",
                           nullable=True),
        "innovation_gate_sigma": P(0.0, "float", "skip a channel's code / carrier update when its innovation "
                                                 "exceeds this many standard deviations (0 = off, the papers' "
                                                 "setting); the innovation still feeds the adaptive R",
                                   lo=0.0),
        "cn0_window_ms": P(200, "int", "C/N0 (M2M4) window of the vector channels: it decides vector lock and "
                                       "coasting, so it sets how fast a lost signal is noticed", lo=20),
        "lock_cn0_dbhz": P(32.0, "float", "vector lock: C/N0 (M2M4, vector.cn0_window_ms) above which a "
                                          "vector channel counts as tracked (records' pll_lock, fixes' "
                                          "n_sats and DOPs; M2M4 on noise alone reads 20-30 dB-Hz)"),
        "coast_mask": P(True, "bool", "while fewer than 4 channels carry signal (C/N0 above lock_cn0_dbhz) the "
                                      "channels without signal are predicted only (no measurement update): "
                                      "the filter coasts on its motion model instead of on noise"),
        "reinit_sigma_m": P(30.0, "float", "an outage the filter cannot bridge: when its 3D position standard "
                                           "deviation passes this while coasting, the channels fall back to "
                                           "scalar tracking and the handover starts again from the next scalar "
                                           "fix (0 = never)", lo=0.0),
        "drop_elevation_deg": P(-2.0, "float", "vector channels whose satellite sets below this elevation are "
                                               "dropped", lo=-90.0, hi=90.0),
        "add_predicted": P(True, "bool", "open channels predicted from the navigation solution for "
                                         "satellites with an ephemeris above navigation.elevation_mask_deg "
                                         "(no acquisition needed)"),
        "adaptive_r": {
            "window": P(500, "int", "innovations (epochs) in the sliding R estimate", lo=2),
            "form": P("paper", "str", "R estimate: paper (C_v + H P+ H^T, as printed), innovation "
                                      "(C_v - H P- H^T) or residual (C_r + H P+ H^T)",
                      choices=("paper", "innovation", "residual")),
            "floor_code_m2": P(10.0, "float", "lower limit of the code R", lo=1e-9),
            "floor_carrier_m2s2": P(1.0, "float", "lower limit of the carrier R", lo=1e-9),
        },
        "polynomial": {
            "position_taps": P(3, "int", "PPF length K of the position predictor (degree 2)", lo=3, hi=8),
            "velocity_taps": P(2, "int", "PPF length K of the velocity predictor (degree 1)", lo=2, hi=8),
            "drift_taps": P(2, "int", "PPF length K of the clock-drift predictor (degree 1)", lo=2, hi=8),
            "chi2_threshold": P(25.0, "float", "manoeuvre detection threshold on the code / carrier "
                                               "innovation chi-square tags (0 = off)", lo=0.0),
            "q_manoeuvre_pos_m2": P(1.0, "float", "manoeuvre Q (added on a detection): position jump "
                                                  "variance", lo=0.0),
            "q_manoeuvre_vel_m2s2": P(0.1, "float", "manoeuvre Q: velocity jump variance ((m/s)^2)", lo=0.0),
            "q_manoeuvre_acc_m2s4": P(1.0, "float", "manoeuvre Q: acceleration jump variance ((m/s^2)^2; "
                                                    "detections repeat while a manoeuvre lasts)", lo=0.0),
            "q_manoeuvre_clock": P(0.01, "float", "manoeuvre Q: clock-drift jump variance ((m/s)^2)", lo=0.0),
            "adaptive_r": P(True, "bool", "residual-form adaptive R (R = C_r + H P H^T over "
                                          "vector.adaptive_r.window epochs)"),
        },
        "cv": {
            "q_velocity": P(1e-3, "float", "per-epoch velocity process noise sigma_v^2 ((m/s)^2)", lo=0.0),
            "q_position": P(0.1, "float", "per-epoch position process noise sigma_p^2 (m^2)", lo=0.0),
            "q_bias": P(1e-7, "float", "per-epoch clock-bias process noise sigma_b^2 (m^2)", lo=0.0),
            "q_drift": P(0.1, "float", "per-epoch clock-drift process noise sigma_d^2 ((m/s)^2)", lo=0.0),
            "psd": P(False, "bool", "read the four q values as continuous white-noise PSDs (Q = q T) "
                                    "instead of per-epoch variances"),
        },
    },
    "output": {
        "path": P(None, "str", "HDF5 output (empty: <input stem>.h5 in the current directory; "
                               "`--output` overrides)", nullable=True),
        "report": P(False, "bool", "write a PNG report beside the HDF5 file (<stem>_report.png)"),
        "rinex": P(False, "bool", "write RINEX 3.04 observation and navigation files (<stem>.obs, <stem>.nav)"),
        "nmea": P(False, "bool", "write NMEA 0183 GGA/RMC/GSA/GSV sentences at the fix rate (<stem>.nmea)"),
        "kml": P(False, "bool", "write a KML track of the fixes (<stem>.kml)"),
        "gpx": P(False, "bool", "write a GPX track of the fixes (<stem>.gpx)"),
        "compression": P("gzip", "str", "compression of the growing run-file datasets (channels, navigation, "
                                         "observables, vector): gzip (level 4), lzf (faster, ~8 % larger) or "
                                         "none; both with the shuffle filter", choices=("none", "lzf", "gzip")),
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
    },
}


#: config keys naming input files; relative paths resolve against the current directory, else the config
#: file's directory, else the repository root (so `configs/*.yaml` can say `../shared/data/...`)
PATH_KEYS = (("input", "path"), ("navigation", "ephemeris"))
REPO_ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def shipped_dir() -> str:
    """The directory of the shipped ``data/`` and ``configs/``: package data ``receiver/_share`` found through
    importlib.resources (in a checkout, links to the repository's own ``data/`` and ``configs/``; in an
    installed wheel, copies), so ``configs/default.yaml`` resolves from any directory."""
    from importlib.resources import files
    return str(files("receiver").joinpath("_share"))


def search_bases() -> list:
    """Fallback directories for relative file names after the current directory (and the referring
    file's directory): the repository root (for ``../shared/...`` next to a checkout) and the shipped
    data/configs."""
    return [REPO_ROOT, shipped_dir()]


def find_file(value):
    """A relative config/scenario file name that does not exist here -> the shipped one (``configs/...``,
    ``data/...``) when there is one; otherwise ``value`` unchanged."""
    v = os.fspath(value)
    if os.path.isabs(v) or os.path.exists(v):
        return value
    for base in search_bases():
        cand = os.path.join(base, v)
        if os.path.exists(cand):
            return os.path.normpath(cand)
    return value


def resolve_path(value: str, config_path=None) -> str:
    if not value or os.path.isabs(value) or os.path.exists(value):
        return value
    bases = ([os.path.dirname(os.path.abspath(os.fspath(config_path)))] if config_path else []) + search_bases()
    for base in bases:
        cand = os.path.join(base, value)
        if os.path.exists(cand):
            return os.path.normpath(cand)
    return value


def load_receiver_config(path=None, overrides=None) -> Section:
    """Load and validate a receiver configuration: the YAML file ``path`` (None: the defaults) merged over
    the schema's defaults, then ``overrides`` applied (a list of ``(dotted_key, value)`` pairs, as
    ``--set``).  ``path`` and the relative file names inside it are looked up as ``gnssrx run`` does
    (current directory, then the checkout and the shipped files); a bad key or value raises
    :class:`receiver.errors.UserError` naming it."""
    if path is not None:
        path = find_file(path)
    raw = read_yaml(path) if path is not None else {}
    for sec, key in PATH_KEYS:
        if isinstance(raw.get(sec), dict) and isinstance(raw[sec].get(key), str):
            raw[sec][key] = resolve_path(raw[sec][key], path)
    files = raw.get("input", {}).get("signal_files") if isinstance(raw.get("input"), dict) else None
    if isinstance(files, dict):
        for v in files.values():
            if isinstance(v, dict) and isinstance(v.get("path"), str):
                v["path"] = resolve_path(v["path"], path)
    cfg = build(RECEIVER_SCHEMA, raw, overrides)
    validate_receiver(cfg)
    return cfg


#: the PRNs each signal has codes for (receiver.gnss.registry's SignalDef.prns; tests/unit/core/test_registries.py)
SIGNAL_PRNS = {"gps_l1ca": tuple(range(1, 33)) + tuple(range(193, 203)), "bds_b1i": tuple(range(1, 64)),
               "gal_e1": tuple(range(1, 51))}
#: signals defined in receiver.gnss (codes, messages) that the receiver stages do not process yet
UNTRACKED_SIGNALS = ("gal_e1",)


#: the signals the vector loops track (receiver/tracking/vector: any mix of them, one clock bias per system)
VECTOR_SIGNALS = ("gps_l1ca", "bds_b1i")


def _prn_text(name: str) -> str:
    return {"gps_l1ca": "1-32 (GPS) and 193-202 (QZSS)", "gal_e1": "1-50"}.get(name, "1-63")


def run_signals(cfg: Section) -> list:
    """The run's signal names: ``signals`` when set (checked: known names, no repeats), else [``signal``]."""
    sigs = list(cfg.signals or [])
    if not sigs:
        return [cfg.signal]
    for s in sigs:
        if s not in SIGNAL_CHOICES:
            raise UserError(f"config key 'signals' must list names of {', '.join(SIGNAL_CHOICES)}; got {s!r}")
    if len(set(sigs)) < len(sigs):
        raise UserError(f"config key 'signals' names a signal twice: {sigs}")
    return sigs


def signal_prns(cfg: Section, name: str) -> list:
    """The PRNs searched for signal ``name`` of the run (acquisition.prns_by_signal, else acquisition.prns
    for the first signal, else all of the signal's PRNs)."""
    by = cfg.acquisition.prns_by_signal or {}
    if name in by:
        return list(by[name])
    if name == run_signals(cfg)[0]:
        return list(cfg.acquisition.prns)
    return list(SIGNAL_PRNS[name])


def validate_receiver(cfg: Section) -> Section:
    """Checks of meaning that span several keys (one-line UserErrors): the IF inside the sampled band,
    a non-empty PRN list (duplicates are removed with a warning)."""
    i = cfg.input
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
    prns = cfg.acquisition.prns
    if not prns:
        raise UserError("config key 'acquisition.prns' is empty: no PRN to search")
    sigs = run_signals(cfg)
    for s in sigs:
        if s in UNTRACKED_SIGNALS:
            key = "signals" if cfg.signals else "signal"
            raise UserError(f"config key '{key}': {s} is not acquired or tracked yet (its codes and navigation "
                            f"message are defined in receiver/gnss; docs/galileo.md)")
    if cfg.vector.enabled and any(s not in VECTOR_SIGNALS for s in sigs):
        raise UserError(f"config key 'vector.enabled': the vector loops track {' and '.join(VECTOR_SIGNALS)} "
                        f"only, not {', '.join(s for s in sigs if s not in VECTOR_SIGNALS)}")
    known = SIGNAL_PRNS.get(sigs[0])
    bad = [p for p in prns if known is not None and p not in known]
    if bad:
        raise UserError(f"config key 'acquisition.prns': signal {sigs[0]} has no PRN {bad[0]} "
                        f"({_prn_text(sigs[0])})")
    for name, v in (i.signal_files or {}).items():
        if name not in sigs[1:]:
            raise UserError(f"config key 'input.signal_files': {name!r} is not one of the run's signals after the "
                            f"first ({', '.join(sigs[1:]) or 'none'}; the first is read from input.path)")
        if not isinstance(v, dict) or set(v) - {"path", "if_hz"} or not isinstance(v.get("path"), str) or \
                isinstance(v.get("if_hz", 0.0), bool) or not isinstance(v.get("if_hz", 0.0), (int, float)) or \
                abs(v.get("if_hz", 0.0)) >= half:
            raise UserError(f"config key 'input.signal_files.{name}' must be {{path: FILE, if_hz: HZ}} with "
                            f"|if_hz| < sample_rate_hz/2, got {v!r}")
    by = cfg.acquisition.prns_by_signal or {}
    for name, lst in by.items():
        if name not in sigs:
            raise UserError(f"config key 'acquisition.prns_by_signal': {name!r} is not one of the run's signals "
                            f"({', '.join(sigs)})")
        if not isinstance(lst, list) or not lst or any(isinstance(p, bool) or not isinstance(p, int) or
                                                      p not in SIGNAL_PRNS[name] for p in lst):
            raise UserError(f"config key 'acquisition.prns_by_signal.{name}' must be a non-empty list of PRNs "
                            f"of {name} ({_prn_text(name)}), got {lst!r}")
    unique = list(dict.fromkeys(prns))
    if len(unique) < len(prns):
        from .errors import warn
        dup = sorted({p for p in prns if prns.count(p) > 1})
        warn(f"acquisition.prns lists PRN {', '.join(map(str, dup))} more than once; each is searched once")
        cfg.acquisition._values["prns"] = unique
    return cfg
