"""The acquisition stage as the receiver runs it, from the configuration: the search, the verification
dwell on the next independent block, the rejection of cross-correlation images, the wider search for a
front-end LO offset and the high-sensitivity second pass (:func:`acquire`).  The pipeline and the channel
manager call :func:`acquire`; the numerical pieces live in :mod:`.code_search` and
:mod:`.high_sensitivity`.
"""
from __future__ import annotations

import numpy as np

from .. import threads
from .config import run_signals
from ..errors import UserError
from ..gnss.registry import get_signal
from ..source.io import SampleReader
from .code_search import _has_energy, reject_cross_correlations, search, verify


def fit_dwell(coherent_ms: int, noncoherent: int, available_ms: float, verify: bool = True):
    """(coherent_ms, noncoherent, verified) of a search that fits ``available_ms`` of input: the search
    and, when ``verify``, its independent verification dwell of the same length.  Fewer non-coherent sums
    first, then a shorter coherent block (whole ms); without room for the dwell (under 2 ms) the search
    alone.  (0, 0, False): not even 1 ms."""
    for room, ver in ((available_ms / 2.0, True), (available_ms, False)) if verify else \
            ((available_ms, False),):
        if room >= coherent_ms:
            return coherent_ms, int(min(noncoherent, room // coherent_ms)), ver
        if room >= 1.0:
            return int(room), 1, ver
    return 0, 0, False


def acquire(cfg, reader: SampleReader, start: int, prns, widen: bool = False, notes=None,
            sensitive: bool = False, known_hz=(), doppler_window=None, signal=None) -> list:
    """Search ``prns`` from file index ``start``: search, verification dwell on the next independent block
    (when the file has it), cross-correlation rejection.  ``widen``: when fewer than 4 satellites are
    found, search the others again over +/- acquisition.lo_search_hz; when fewer than
    acquisition.high_sensitivity.min_found, search them with the high-sensitivity pass
    (receiver.acquisition.high_sensitivity).  ``sensitive``: run that pass on the PRNs not found whatever the count
    (cold searches while few channels track; ``known_hz``: their Dopplers narrow its range).  Lines for
    the user are appended to ``notes`` (a list).  ``doppler_window``: (centre, half width) Hz searched
    instead of the configured +/- acquisition.doppler_max_hz (the channel manager's cold searches once a
    fix gives the clock drift).  ``signal``: the SignalDef searched (default: the run's first signal)."""
    a = cfg.acquisition
    fs, if_hz = reader.fs, reader.if_hz
    sig = signal if signal is not None else get_signal(run_signals(cfg)[0])
    notes = [] if notes is None else notes
    if sig.name == "gal_e1":
        return acquire_galileo(cfg, reader, start, prns, doppler_window)
    # the search needs T_coh x K (the verification dwell another T_coh x K); the fine Doppler estimate
    # uses up to 200 ms (20 blocks of 10 ms) where the file has them
    m, k, pfa = a.coherent_ms, a.noncoherent, a.pfa
    dwell = int(round(m * k * 1e-3 * fs))
    block = reader.read(start, max(2 * dwell, int(0.2 * fs)))
    if len(block) < 2 * dwell:
        # a short file (or its end): the search and its verification dwell fitted into what there is
        m, k, verified = fit_dwell(m, k, len(block) / fs * 1e3, a.verify)
        if m == 0:
            raise UserError("input too short for acquisition "
                            f"({len(block) / fs * 1e3:.1f} ms available, at least 1 needed)")
        if not verified:
            pfa = a.pfa / max(len(prns), 1)     # no second look: the Pfa holds for all PRNs together
        if (m, k) != (a.coherent_ms, a.noncoherent) and widen:
            notes.append(f"acquisition     {len(block) / fs * 1e3:.0f} ms of input: searched {m} ms x {k}"
                         + (" with a verification dwell of as many" if verified else
                            f" without verification dwell (Pfa {pfa:.1e} per PRN)"))
        dwell = int(round(m * k * 1e-3 * fs))

    centre = getattr(reader, "doppler_centre_hz", 0.0)     # set below once a common LO offset is seen

    def _search(prns_, dmax):
        c_ = centre if dmax == a.doppler_max_hz else 0.0
        if doppler_window is not None and dmax == a.doppler_max_hz:
            c_, dmax = doppler_window
        res_ = search(block, start, fs, if_hz, prns_, m, k, dmax,
                      a.doppler_step_hz, pfa, a.threshold, signal=sig, width_ratio=a.width_ratio,
                      doppler_center_hz=c_)
        todo = [r for r in res_ if r.detected and a.verify and len(block) >= 2 * dwell]
        # the dwells are independent: on the thread pool (the same result per detection)
        oks = threads.map_ordered(lambda r: verify(block[dwell:2 * dwell], start + dwell, fs, if_hz, r,
                                                   m, k, a.doppler_step_hz, pfa,
                                                   a.threshold, signal=sig), todo)
        for r, ok in zip(todo, oks):
            r.verified = int(ok)
            if not ok:
                r.detected, r.reason = False, "verify"
        return res_

    res = _search(prns, a.doppler_max_hz)
    reject_cross_correlations(res, m, fs=fs, signal=sig)
    found = sum(r.detected for r in res)
    if widen and found < 4 and a.lo_search_hz > a.doppler_max_hz:
        missing = [r.prn for r in res if not r.detected]
        wide = {r.prn: r for r in _search(missing, a.lo_search_hz)}
        res = [wide.get(r.prn, r) for r in res]
        reject_cross_correlations(res, m, fs=fs, signal=sig)
        notes.append(f"acquisition     {found} satellite(s) within +/-{a.doppler_max_hz / 1e3:g} kHz: searched "
                     f"again over +/-{a.lo_search_hz / 1e3:g} kHz (front-end LO offset?), "
                     f"{sum(r.detected for r in res)} found")
    hs = a.high_sensitivity
    if hs.enabled and sig.bit_ms(1) == 20 and sig.secondary(1) is None and _has_energy(block) and \
            (sensitive or (widen and sum(r.detected for r in res) < hs.min_found)):       # GPS L1 C/A
        from .high_sensitivity import second_pass
        res, line = second_pass(a, reader, start, if_hz, res, sig, known_hz, centre)
        if line and widen:
            notes.append(line)
    dop = [r.doppler_hz for r in res if r.detected]
    if len(dop) >= 3 and abs(np.median(dop) - centre) > a.lo_warn_hz:
        med = float(np.median(dop))
        notes.append(f"warning         the {len(dop)} satellites found share a common Doppler offset of "
                     f"{med / 1e3:+.2f} kHz (median): front-end LO / oscillator error of about "
                     f"{-med / sig.carrier_hz * 1e6:+.1f} ppm; later searches are centred there")
        reader.doppler_centre_hz = round(med / 100.0) * 100.0     # re-acquisitions search around it
    return res



#: 4-ms blocks summed non-coherently by the Galileo E1 search (20 ms: 45 dB-Hz signals at ~19 dB, 38 at ~12 dB
#: above the noise floor of the grid's largest noise cell)
GAL_NONCOHERENT = 5


def acquire_galileo(cfg, reader: SampleReader, start: int, prns, doppler_window=None) -> list:
    """Galileo E1 search (receiver.acquisition.galileo.search: E1-B + E1-C BOC(1,1), BOC side peak resolved) of
    ``prns`` from file index ``start`` over acquisition.doppler_max_hz (or ``doppler_window``: centre, half
    width) at acquisition.pfa; results not detected get reason ``threshold``."""
    from .galileo import search as gal_search
    a = cfg.acquisition
    fs = reader.fs
    n = int(round(fs * 4e-3)) * GAL_NONCOHERENT
    block = reader.read(start, n)
    if len(block) < n:
        raise UserError(f"input too short for Galileo acquisition ({len(block) / fs * 1e3:.1f} ms available, "
                        f"{n / fs * 1e3:.0f} needed)")
    centre = getattr(reader, "doppler_centre_hz", 0.0)
    dmax = a.doppler_max_hz
    if doppler_window is not None:
        centre, dmax = doppler_window
    res = gal_search(block, start, fs, reader.if_hz, prns, noncoherent=GAL_NONCOHERENT, doppler_max_hz=dmax,
                     doppler_center_hz=centre, pfa=a.pfa, threshold=a.threshold)
    for r in res:
        r.reason = "" if r.detected else "threshold"
    return res
