"""The ``signal`` / ``signals`` keys and the ``acquisition`` section of the receiver config (schema fragments
of the acquisition stage: the signals and PRNs searched) and their checks; receiver/schema.py assembles
them into the receiver's schema."""
from __future__ import annotations

from ..config import P, Section
from ..errors import UserError, warn
from ..gnss.registry import SIGNAL_NAMES, get_signal

#: signals defined in receiver.gnss (codes, messages) that the receiver stages do not process yet
UNTRACKED_SIGNALS = ()
#: signals tracked as a second band of the first signal's satellites, from a file of their own
#: (input.signal_files), aided by the first signal's channels (receiver/dualband.py; docs: Dual frequency)
BAND_SIGNALS = ("gps_l5", "gal_e5a")
#: the signal whose channels aid each second-band signal (the same satellites' L1 / E1 channels)
BAND_BASE = {"gps_l5": "gps_l1ca", "gal_e5a": "gal_e1"}

#: the PRNs each signal has codes for (receiver.gnss.registry's SignalDef.prns)
SIGNAL_PRNS = {name: tuple(get_signal(name).prns) for name in SIGNAL_NAMES}

#: the top-level keys naming the run's signals (choices: receiver.gnss.registry)
SIGNALS_SCHEMA = {
    "signal": P("gps_l1ca", "str", "signal to acquire, track and navigate with: gps_l1ca (GPS and QZSS "
                                   "L1 C/A, LNAV), bds_b1i (BeiDou B1I, D1/D2 messages) or gal_e1 (Galileo E1 OS, "
                                   "I/NAV; docs: Galileo E1); gps_l5 (GPS L5 Q5 pilot) and gal_e5a (Galileo E5a-Q "
                                   "pilot) only as second bands, e.g. signals: [gps_l1ca, gps_l5] or [gal_e1, "
                                   "gal_e5a], with input.signal_files (docs: Dual frequency)",
                choices=SIGNAL_NAMES),
    "signals": P([], "list", "several signals in one run (e.g. [gps_l1ca, gal_e1, bds_b1i]; empty: `signal` alone): "
                             "every signal is acquired and tracked from the same input (input.if_hz is the IF "
                             "of the first; the others sit at if_hz + their carrier - the first's), and the "
                             "fixes use all systems with an inter-system clock bias (docs: BeiDou and multi-GNSS)"),
}

SCHEMA = {
    "prns": P(list(range(1, 33)), "list_int", "PRNs searched (gps_l1ca: GPS 1-32 and QZSS 193-202 = "
                                              "J01-J10; bds_b1i: 1-63; gal_e1: 1-50)", lo=1, hi=202),
    "prns_by_signal": P({}, "dict", "runs over several signals: PRNs searched per signal name (e.g. "
                                    "{bds_b1i: [6, 7, 8]}); a signal not listed searches acquisition.prns "
                                    "when it is the first of `signals`, else all its PRNs"),
    "coherent_ms": P(4, "int", "coherent integration per non-coherent step (ms)", lo=1, hi=10),
    "band_aiding": P(True, "bool", "second band (gps_l5 / gal_e5a in `signals`): search each satellite's "
                                   "L5 / E5a signal around the code phase and Doppler of its L1 / E1 channel "
                                   "(false: every code phase, the full Doppler range; docs: Dual frequency)"),
    "band_ms": P(10, "int", "second band: 1-ms correlations summed non-coherently per L5 / E5a search", lo=1,
                 hi=200),
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
                                   "the others again with the high-sensitivity pass (10-ms blocks, alternate "
                                   "half-bit sums, code Doppler compensated, Doppler range narrowed by the "
                                   "satellites found)"),
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
    "predicted": {
        "enabled": P(True, "bool", "after a fix, search every satellite in view that no channel tracks (GPS / "
                                   "QZSS L1 C/A, with an ephemeris) around its code phase and Doppler "
                                   "predicted from a tracked satellite and the fix, with a long integration "
                                   "(docs: acquisition, predicted search): finds satellites far weaker than "
                                   "the cold search does"),
        "coherent_ms": P(10, "int", "coherent block (ms; divides 20)", choices=(1, 2, 4, 5, 10)),
        "noncoherent": P(50, "int", "blocks summed non-coherently (alternate half-bit sums, each block "
                                    "moved back by its code drift)", lo=2, hi=200),
        "window_chips": P(2.0, "float", "code-phase half-window around the prediction (chips)", lo=0.5, hi=100.0),
        "doppler_hz": P(50.0, "float", "Doppler half-window around the prediction (Hz)", lo=0.0, hi=2000.0),
        "pfa": P(1e-4, "float", "false-alarm probability over the window's cells", lo=1e-12, hi=0.5),
        "every_s": P(2.0, "float", "a satellite not found is searched again after this long, the interval "
                                   "doubling after each failure up to 4 x this", lo=0.1),
    },
}


def run_signals(cfg: Section) -> list:
    """The run's signal names: ``signals`` when set (checked: known names, no repeats), else [``signal``]."""
    sigs = list(cfg.signals or [])
    if not sigs:
        return [cfg.signal]
    for s in sigs:
        if s not in SIGNAL_NAMES:
            raise UserError(f"config key 'signals' must list names of {', '.join(SIGNAL_NAMES)}; got {s!r}")
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


def _prn_text(name: str) -> str:
    return {"gps_l1ca": "1-32 (GPS) and 193-202 (QZSS)", "gal_e1": "1-50", "gps_l5": "1-32",
            "gal_e5a": "1-36 and 40-50"}.get(name, "1-63")


def check_prns(a: Section):
    """acquisition.prns is not empty."""
    if not a.prns:
        raise UserError("config key 'acquisition.prns' is empty: no PRN to search")


def check_signals(cfg: Section, sigs: list):
    """The run's signals are ones the receiver stages process."""
    key = "signals" if cfg.signals else "signal"
    for b in (s for s in sigs if s in BAND_SIGNALS):
        base = BAND_BASE[b]
        if base not in sigs or sigs.index(b) < sigs.index(base) or sigs[0] in BAND_SIGNALS:
            raise UserError(f"config key '{key}': {b} is tracked as the second band of {base} (aided by its "
                            f"channels): list it after {base}, e.g. signals: [{base}, {b}], with its file in "
                            f"input.signal_files (docs: Dual frequency)")
    for s in sigs:
        if s in UNTRACKED_SIGNALS:
            key = "signals" if cfg.signals else "signal"
            raise UserError(f"config key '{key}': {s} is not acquired or tracked yet (its codes and navigation "
                            f"message are defined in receiver/gnss; docs/galileo.md)")


def check(a: Section, sigs: list):
    """acquisition.prns exist for the first of the run's signals ``sigs``."""
    prns = a.prns
    known = SIGNAL_PRNS.get(sigs[0])
    bad = [p for p in prns if known is not None and p not in known]
    if bad:
        raise UserError(f"config key 'acquisition.prns': signal {sigs[0]} has no PRN {bad[0]} "
                        f"({_prn_text(sigs[0])})")


def check_by_signal(a: Section, sigs: list):
    """acquisition.prns_by_signal lists PRNs of the run's signals; duplicates in acquisition.prns are
    removed with a warning."""
    by = a.prns_by_signal or {}
    for name, lst in by.items():
        if name not in sigs:
            raise UserError(f"config key 'acquisition.prns_by_signal': {name!r} is not one of the run's signals "
                            f"({', '.join(sigs)})")
        if not isinstance(lst, list) or not lst or any(isinstance(p, bool) or not isinstance(p, int) or
                                                      p not in SIGNAL_PRNS[name] for p in lst):
            raise UserError(f"config key 'acquisition.prns_by_signal.{name}' must be a non-empty list of PRNs "
                            f"of {name} ({_prn_text(name)}), got {lst!r}")
    prns = a.prns
    unique = list(dict.fromkeys(prns))
    if len(unique) < len(prns):
        dup = sorted({p for p in prns if prns.count(p) > 1})
        warn(f"acquisition.prns lists PRN {', '.join(map(str, dup))} more than once; each is searched once")
        a._values["prns"] = unique
