#!/usr/bin/env python3
"""Galileo-only acceptance run (issue 33): the project's simulator makes a static Galileo E1 recording
(E1-B with I/NAV, E1-C with CS25, BOC(1,1)); then acquisition (receiver/acquisition/galileo.py), E1-C tracking
with CS25 wiped (receiver/tracking/gal.py), I/NAV decoding (receiver/gnss/gal_inav.py), pseudoranges from
the decoded GST and a least-squares fix every ``--rate`` s with the decoded ephemerides.  Prints: the
satellites acquired, whether each decoded ephemeris equals the simulated one (every field within one LSB),
the time of the first fix, and the 3D / horizontal / vertical error against the truth file.

This path runs beside the receiver pipeline (which does not track gal_e1 yet); the PVT here is a plain
iterative least squares (Sagnac, satellite clock with relativity and BGD(E1,E5b), Saastamoinen troposphere as
simulated, no ionosphere: the scenario has none).

    python scripts/bench/accuracy_galileo.py --out /tmp/gal_acc [--duration 45] [--cn0 45] [--seed 1] [--dll-bw 8]
                                     [--smooth-s 10] [--recording FILE] [--reuse-tracking]

The recording is configs/scenarios/static_galileo.yaml (static, 4 MS/s int8 I/Q, no ionosphere).
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]

from receiver.acquisition.galileo import refine_pilot, search  # noqa: E402
from receiver.gnss.atmosphere import saastamoinen_m  # noqa: E402
from receiver.gnss.ephemeris import earth_rotation, sat_state  # noqa: E402
from receiver.gnss.gal_inav import EPH_LSB, InavDecoder  # noqa: E402
from receiver.gnss.geodesy import azel, ecef2lla  # noqa: E402
from receiver.gnss.signals import C_LIGHT  # noqa: E402
from receiver.tracking.gal import GalChannel  # noqa: E402


def simulate(out: Path, duration: float, cn0: float, seed: int) -> Path:
    """configs/scenarios/static_galileo.yaml with the duration, C/N0 and seed of the command line."""
    from receiver.sim.simulate import simulate as sim
    rec = out / "gal.bin"
    sim(ROOT / "configs" / "scenarios" / "static_galileo.yaml", rec,
        [("time.duration_s", duration), ("time.seed", seed), ("cn0.dbhz", cn0)], progress=False)
    return rec


def _tx_time(ep, events):
    """GST (= GPS) transmit time at each epoch start of a channel, from the decoder's first page event (an
    (event, symbol index at which it was emitted) pair); NaN before that index."""
    tx = np.full(len(ep.sample), np.nan)
    if not events:
        return tx
    ev, known_at = events[0]
    i = np.arange(len(ep.sample))
    tx = ev.tow_s + (i - ev.bit_index) * 4e-3 + ep.code_phase / 1.023e6
    tx[i < known_at] = np.nan
    return tx


def _interp(ep, values, s):
    """values (per epoch start) at sample s, linearly; None outside the epochs."""
    j = int(np.searchsorted(ep.sample, s)) - 1
    if j < 0 or j + 1 >= len(ep.sample) or not (np.isfinite(values[j]) and np.isfinite(values[j + 1])):
        return None
    return values[j] + (values[j + 1] - values[j]) * (s - ep.sample[j]) / (ep.sample[j + 1] - ep.sample[j])


def wls(sats, x0):
    """sats: list of (pseudorange m, sat pos at transmission (ECEF at tx), sat clock s); returns (x, b)."""
    x = np.array(x0, float)
    b = 0.0
    for _ in range(10):
        rows, res = [], []
        lat, lon, h = ecef2lla(x[None, :])
        for pr, ps, clk in sats:
            tau = np.linalg.norm(ps - x) / C_LIGHT
            pr_rot = earth_rotation(ps, tau)
            los = pr_rot - x
            rng = np.linalg.norm(los)
            u = los / rng
            trop = 0.0
            if np.linalg.norm(x) > 6e6:
                el = float(azel(x, pr_rot)[1])
                trop = float(saastamoinen_m(np.radians(lat[0]), h[0], max(el, 0.05)))
            pred = rng + b + trop - C_LIGHT * clk
            rows.append(np.concatenate([-u, [1.0]]))
            res.append(pr - pred)
        H, r = np.array(rows), np.array(res)
        dx = np.linalg.lstsq(H, r, rcond=None)[0]
        x += dx[:3]
        b += dx[3]
        if np.linalg.norm(dx[:3]) < 1e-4:
            break
    return x, b, r


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", required=True, help="directory for the recording")
    ap.add_argument("--duration", type=float, default=45.0)
    ap.add_argument("--cn0", type=float, default=45.0)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--rate", type=float, default=1.0, help="fix interval (s)")
    ap.add_argument("--recording", help="use this recording (made by an earlier run) instead of simulating")
    ap.add_argument("--dll-bw", type=float, default=8.0,
                    help="DLL noise bandwidth (Hz; the pipeline's Galileo channels use 8)")
    ap.add_argument("--reuse-tracking", action="store_true",
                    help="take the tracking and decoding of an earlier run from OUT/gal_epochs.pkl")
    ap.add_argument("--smooth-s", type=float, default=10.0,
                    help="carrier-smoothing (Hatch) time constant of the pseudoranges (s); 0: raw code")
    a = ap.parse_args(argv)
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.time()
    rec = Path(a.recording) if a.recording else simulate(out, a.duration, a.cn0, a.seed)
    print(f"recording {rec} ({time.time() - t0:.1f} s)")
    import h5py
    truth = h5py.File(str(rec)[:-4] + ".truth.h5")
    fs = float(truth.attrs["sample_rate_hz"])
    raw = np.memmap(rec, np.int8, "r")
    n_samp = raw.size // 2
    blk = raw[:2 * int(fs * 0.2)].astype(np.float32)
    x0 = (blk[0::2] + 1j * blk[1::2]).astype(np.complex64)
    t1 = time.time()
    acq = [] if a.reuse_tracking and (out / "gal_epochs.pkl").exists() else [
        r for r in search(x0, 0, fs, 0.0, range(1, 37), noncoherent=5, doppler_max_hz=5000.0) if r.detected]
    print(f"acquired {[r.prn for r in acq]} ({time.time() - t1:.1f} s)")
    chans = {}
    for r in acq:
        dop, off = refine_pilot(x0, fs, 0.0, r.prn, r.code_phase_chips, r.doppler_hz)
        chans[r.prn] = GalChannel(r.prn, fs, 0.0, 0, r.code_phase_chips, dop, off, dll_bw_hz=a.dll_bw)
    t1 = time.time()
    n_ep = int(n_samp / fs / 4e-3) + 2
    eps, decs, evs, avail = {}, {}, {}, {}
    cache = out / "gal_epochs.pkl"
    if a.reuse_tracking and cache.exists():
        import pickle
        eps, decs, evs, avail = pickle.loads(cache.read_bytes())
        chans = {}
    for prn, ch in chans.items():
        ep = ch.run(raw, n_ep)
        # the decoder is fed 1 s at a time as a running receiver would: the symbol index at which it first
        # holds an ephemeris is when that satellite can be used
        dec = InavDecoder(prn)
        ev, eph_at = [], None
        for k in range(0, len(ep.sample), 250):
            ev += [(e, k + 250) for e in dec.feed(ep.prompt_b.real[k:k + 250], k)]
            if eph_at is None and dec.ephemeris is not None:
                eph_at = k + 250
        eps[prn], decs[prn], evs[prn], avail[prn] = ep, dec, ev, eph_at
        print(f"  E{prn:02d}: {len(ep.sample)} epochs, C/N0 (pilot) {np.median(ep.cn0_dbhz[250:]):.1f} dB-Hz, "
              f"pages {dec.pages_ok} ok / {dec.crc_failures} CRC failures, ephemeris "
              f"{'decoded' if dec.ephemeris is not None else 'none'}")
    print(f"tracking + decoding {time.time() - t1:.1f} s")
    if chans:
        import pickle
        cache.write_bytes(pickle.dumps((eps, decs, evs, avail)))
    # the decoded ephemerides against the simulated ones
    from receiver.sim.gal_constellation import gal_nominal_content
    sim_content = gal_nominal_content(ROOT / "data" / "gal_nominal_constellation.yaml", 2300,
                                      float(truth.attrs["start_gps_tow_s"]))
    eq = {}
    for prn, dec in decs.items():
        if dec.ephemeris is None:
            continue
        s = sim_content[prn].eph
        eq[prn] = all(abs(getattr(dec.ephemeris, k) - getattr(s, k)) <= lsb for k, lsb in EPH_LSB.items())
    print(f"decoded ephemerides equal to the simulated ones within one LSB: {eq}")
    # fixes
    tx = {p: _tx_time(eps[p], evs[p]) for p in eps}
    rx_truth = truth["receiver"]
    t_truth, ecef_truth = rx_truth["time_s"][:], rx_truth["ecef"][:]
    fixes = []
    T0 = None
    xg = np.array([0.0, 0.0, 0.0]) + 1.0
    lam = C_LIGHT / 1575.42e6
    smooth = {}                                 # prn -> (smoothed pseudorange - c T, carrier range, count)
    for s in np.arange(int(fs * 1.0), n_samp - int(fs * 0.1), int(fs * a.rate)):
        sats = []
        for p, ep in eps.items():
            ttx = _interp(ep, tx[p], s)
            if ttx is None:
                continue                        # no page time yet
            cyc = _interp(ep, ep.carr_cycles, s)
            sats.append((p, ttx, cyc, avail[p] is not None and ep.sample[min(avail[p], len(ep.sample) - 1)] <= s))
        if not sats:
            continue
        if T0 is None:
            T0 = max(t for _, t, _, _ in sats) + 0.08 - s / fs
        T = T0 + s / fs
        obs = []
        for p, ttx, cyc, has_eph in sats:
            pr = C_LIGHT * (T - ttx)
            rng_c = -lam * cyc                  # carrier range change (IF 0; Doppler > 0: range shrinking)
            if a.smooth_s > 0:                  # Hatch filter: code smoothed by the carrier (no ionosphere)
                old = smooth.get(p)
                m = 1 if old is None else min(old[2] + 1, max(1, round(a.smooth_s / a.rate)))
                ps = pr if old is None else pr / m + (m - 1) / m * (old[0] + rng_c - old[1])
                smooth[p] = (ps, rng_c, m)
                pr = ps
            if has_eph:                         # the satellite's ephemeris decoded by now
                pos, _, clk, _ = sat_state(decs[p].ephemeris, ttx)
                obs.append((pr, np.asarray(pos), float(clk)))
        if len(obs) < 4:
            continue
        xg, b, r = wls(obs, xg)
        if np.linalg.norm(xg) < 6.0e6:          # first iterations from the Earth's centre: again
            xg, b, r = wls(obs, xg)
        truth_pos = np.array([np.interp(s / fs, t_truth, ecef_truth[:, k]) for k in range(3)])
        fixes.append((s / fs, len(obs), xg.copy(), truth_pos, float(np.sqrt(np.mean(r ** 2)))))
    if not fixes:
        print("no fix")
        return 1
    err = np.array([f[2] - f[3] for f in fixes])
    lat, lon, _ = ecef2lla(fixes[0][3][None, :])
    la, lo = np.radians(lat[0]), np.radians(lon[0])
    e = -np.sin(lo) * err[:, 0] + np.cos(lo) * err[:, 1]
    nn = -np.sin(la) * np.cos(lo) * err[:, 0] - np.sin(la) * np.sin(lo) * err[:, 1] + np.cos(la) * err[:, 2]
    u = np.cos(la) * np.cos(lo) * err[:, 0] + np.cos(la) * np.sin(lo) * err[:, 1] + np.sin(la) * err[:, 2]
    d3 = np.sqrt(np.mean(np.sum(err ** 2, axis=1)))
    print(f"ephemeris available (s after the first sample): "
          f"{ {p: round(eps[p].sample[min(v, len(eps[p].sample) - 1)] / fs, 1) for p, v in avail.items() if v} }")
    print(f"fixes: {len(fixes)}, first at {fixes[0][0]:.1f} s after the first sample, satellites "
          f"{min(f[1] for f in fixes)}-{max(f[1] for f in fixes)}")
    print(f"3D RMS {d3:.3f} m, horizontal RMS {np.sqrt(np.mean(e ** 2 + nn ** 2)):.3f} m, vertical RMS "
          f"{np.sqrt(np.mean(u ** 2)):.3f} m, mean ENU ({e.mean():.2f}, {nn.mean():.2f}, {u.mean():.2f}) m, "
          f"max 3D {np.max(np.linalg.norm(err, axis=1)):.3f} m")
    return 0


if __name__ == "__main__":
    sys.exit(main())
