"""Acceptance matrix of issue 16 (real front ends): acquisition integrity against spurs, strong signals and
quantisation, and fixes under CW interference, on the project's own simulator.

Acquisition cases (``--seeds`` seeds each, ``--acq-s`` second recordings, default config, `acquire` as
the receiver runs it: input conditioning, search, verification dwell, cross-correlation rejection):
    noise      no satellite signal at all (every C/N0 at -20 dB-Hz)
    clean      the sky, no impairment
    cw F P     one CW tone at F Hz from the carrier, P dB above the noise power
    strong     the highest satellite at 55 dB-Hz, the others 38-45 dB-Hz
    2bit       2-bit quantisation with AGC
    lo +20k    oscillator error -12.7 ppm: every carrier ~20 kHz off (the widened search must find them)
The sky: embedded constellation, C/N0 38 dB-Hz at the horizon to 45 dB-Hz at zenith.  Per case: false
PRNs (detected, not simulated) summed over seeds, and detected / simulated satellites above 10 deg.

Fix cases (``--fix-seeds``, ``--fix-s`` second static runs): no tone, CW +3 kHz at 30 dB and 40 dB; 3D
RMS error of the fixes against the truth and the mean C/N0 loss against the same seed without the tone.

    PYTHONPATH=. python scripts/bench/accuracy_frontends.py [--seeds 5] [--fix-seeds 1] [--quick]
"""
from __future__ import annotations

import argparse
import os
import tempfile
import time

import h5py
import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from receiver.schema import load_receiver_config  # noqa: E402
from receiver.acquisition.stage import acquire  # noqa: E402
from receiver.pipeline import open_input, run  # noqa: E402
from receiver.sim.simulate import simulate  # noqa: E402

SKY = {"cn0": {"mode": "elevation", "dbhz": 45.0, "horizon_dbhz": 38.0}}


def acq_cases(quick=False):
    cases = [("noise", {"cn0": {"mode": "constant", "dbhz": -20.0}}), ("clean", {})]
    freqs = (0.0, 3000.0, 250e3, -600e3)
    powers = (30.0,) if quick else (20.0, 30.0, 40.0)
    for f in freqs:
        for p in powers:
            cases.append((f"cw {f / 1e3:+g}k {p:g}dB",
                          {"impairments": {"tones": [{"freq_hz": f, "power_db": p}]}}))
    cases.append(("strong 55", "strong"))
    cases.append(("2bit", {"impairments": {"quantization": {"bits": 2}}, "frontend": {"format": "int8_iq"}}))
    # beyond the list: an oscillator 12.7 ppm slow puts every carrier ~ +20 kHz off (LO offset)
    cases.append(("lo +20k", {"clock": {"freq_error_ppm": -12.7}}))
    # beyond the list: a CW into a 2-bit ADC (the AGC sets on the tone: hard limiting, a comb of
    # harmonics and intermodulation every 6 kHz, and the satellites suppressed by the limiter)
    for p in (20.0, 30.0):
        cases.append((f"2bit+cw +3k {p:g}dB", {"impairments": {"quantization": {"bits": 2}, "tones": [
            {"freq_hz": 3000.0, "power_db": p}]}, "frontend": {"format": "int8_iq"}}))
    return cases


def scenario(extra, seed, duration):
    # int16 with headroom: a 40 dB tone is not clipped (an int8 file with noise sigma 8 would hard-limit
    # it); the 2-bit case writes its levels into int8
    sc = {"time": {"duration_s": duration, "seed": seed}, "output": {"block_s": 0.25},
          "frontend": {"format": "int16_iq", "noise_sigma": 50.0}}
    sc.update({k: dict(v) for k, v in SKY.items()})
    for k, v in (extra or {}).items():
        sc[k] = {**sc.get(k, {}), **v}
    return sc


def truth_sky(truth_path):
    """{prn: max elevation} of the satellites that carry a signal (visible, C/N0 > 0)."""
    out = {}
    with h5py.File(truth_path, "r") as f:
        for name, g in f["satellites"].items():
            vis = g["visible"][()].astype(bool) & (g["cn0_dbhz"][()] > 0)
            if vis.any():
                out[int(g.attrs.get("prn", name[1:]))] = float(g["elevation_deg"][()][vis].max())
    return out


def highest_prn(tmp, seed, duration):
    p = simulate(scenario({}, seed, 0.05), os.path.join(tmp, "probe.bin"), progress=False)
    sky = truth_sky(p["truth"])
    for q in p.values():
        os.remove(q)
    return max(sky, key=sky.get)


def run_acq_case(tmp, name, extra, seeds, duration):
    false_prns, det, sim_hi = 0, 0, 0
    wall = 0.0
    for seed in seeds:
        if extra == "strong":
            extra_s = {"cn0": {"per_prn": {highest_prn(tmp, seed, duration): 55.0}}}
        else:
            extra_s = extra
        paths = simulate(scenario(extra_s, seed, duration), os.path.join(tmp, "acq.bin"), progress=False)
        sky = truth_sky(paths["truth"])
        if name == "noise":
            sky = {}
        cfg = load_receiver_config(paths["yaml"], [("input.path", paths["if"])])
        t0 = time.process_time()
        reader = open_input(cfg)
        res = acquire(cfg, reader, reader.first, cfg.acquisition.prns, widen=True)
        wall += time.process_time() - t0
        found = {r.prn for r in res if r.detected}
        false_prns += len(found - set(sky))
        hi = {p for p, e in sky.items() if e >= 10.0}
        sim_hi += len(hi)
        det += len(found & hi)
        for q in paths.values():
            os.remove(q)
    return false_prns, det, sim_hi, wall / len(seeds)


def run_fix_case(tmp, extra, seed, duration, tag):
    paths = simulate(scenario(extra, seed, duration), os.path.join(tmp, f"fix_{tag}.bin"), progress=False)
    out = os.path.join(tmp, f"fix_{tag}.h5")
    cfg = load_receiver_config(paths["yaml"], [("input.path", paths["if"]), ("output.path", out)])
    t0 = time.process_time()
    summ = run(cfg, quiet=True)
    cpu = time.process_time() - t0
    with h5py.File(paths["truth"], "r") as f:
        t_true, x_true = f["receiver/time_s"][()], f["receiver/ecef"][()]
    with h5py.File(out, "r") as f:
        nav = f["navigation"]
        t = nav["time_s"][()] - f.attrs.get("first_sample", 0) / cfg.input.sample_rate_hz \
            if "time_s" in nav else np.zeros(0)
        ecef = nav["ecef"][()] if "ecef" in nav else np.zeros((0, 3))
        tones = f["conditioning/freq_hz"][()] if "conditioning" in f else []
    for q in paths.values():
        os.remove(q)
    if len(ecef):
        ref = np.stack([np.interp(t, t_true, x_true[:, i]) for i in range(3)], axis=1)
        rms = float(np.sqrt(np.mean(np.sum((ecef - ref) ** 2, axis=1))))
    else:
        rms = float("nan")
    return {"rms": rms, "n_fixes": summ.n_fixes, "cn0": summ.mean_cn0, "cpu": cpu, "tones": list(tones),
            "notes": summ.notes}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--acq-s", type=float, default=1.0)
    ap.add_argument("--fix-seeds", type=int, default=1)
    ap.add_argument("--fix-s", type=float, default=40.0)
    ap.add_argument("--quick", action="store_true", help="30 dB tones only")
    ap.add_argument("--skip-acq", action="store_true")
    ap.add_argument("--skip-fix", action="store_true")
    ap.add_argument("--cases", default="", help="only the acquisition cases whose name contains this")
    args = ap.parse_args()
    tmp = tempfile.mkdtemp(prefix="frontend_acc_")
    seeds = list(range(1, args.seeds + 1))
    ok_all = True
    if not args.skip_acq:
        print(f"acquisition: {len(seeds)} seeds x {args.acq_s:g} s, default config")
        print(f"{'case':<20} {'false PRNs':>10} {'detected >10deg':>16} {'rate':>6} {'cpu/acq s':>9}")
        for name, extra in acq_cases(args.quick):
            if args.cases not in name:
                continue
            fp, det, n, cpu = run_acq_case(tmp, name, extra, seeds, args.acq_s)
            rate = det / n if n else 1.0
            ok = fp == 0 and rate >= 0.9
            informational = name.startswith(("lo ", "2bit+cw"))      # beyond the acceptance list
            ok_all &= ok or informational
            print(f"{name:<20} {fp:>10d} {f'{det}/{n}':>16} {100 * rate:5.1f}% {cpu:9.1f}"
                  + ("" if ok else "   (not met; not in the acceptance list)" if informational else "   FAIL"),
                  flush=True)
    if not args.skip_fix:
        print(f"\nfixes: {args.fix_seeds} seed(s) x {args.fix_s:g} s static, default config")
        print(f"{'seed':>4} {'case':<14} {'fixes':>6} {'3D RMS m':>9} {'C/N0 loss dB':>12} {'cpu s':>7}  tones")
        for seed in range(1, args.fix_seeds + 1):
            base = run_fix_case(tmp, {}, seed, args.fix_s, "base")
            print(f"{seed:>4} {'no tone':<14} {base['n_fixes']:>6d} {base['rms']:9.2f} {'':>12} "
                  f"{base['cpu']:7.1f}  {base['tones']}", flush=True)
            for p, lim in ((30.0, 5.0), (40.0, 10.0)):
                r = run_fix_case(tmp, {"impairments": {"tones": [{"freq_hz": 3000.0, "power_db": p}]}},
                                 seed, args.fix_s, f"cw{p:g}")
                common = sorted(set(r["cn0"]) & set(base["cn0"]))
                loss = float(np.mean([base["cn0"][q] - r["cn0"][q] for q in common])) if common else np.nan
                ok = r["rms"] <= lim and (p != 30.0 or loss <= 2.0)
                ok_all &= ok
                print(f"{seed:>4} {f'CW +3k {p:g} dB':<14} {r['n_fixes']:>6d} {r['rms']:9.2f} {loss:12.2f} "
                      f"{r['cpu']:7.1f}  {[round(float(x), 1) for x in r['tones']]}" + ("" if ok else "   FAIL"),
                      flush=True)
    print("\nall met" if ok_all else "\nNOT all met")


if __name__ == "__main__":
    main()
