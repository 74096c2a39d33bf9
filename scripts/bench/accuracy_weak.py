"""High-sensitivity acceptance (issue 17): the weak-signal scenarios over seeds, default config.

For each scenario (configs/scenarios/hs_*.yaml) and seed: simulate (when the recording is absent), run the
receiver with configs/default.yaml (plus ``--set`` overrides, e.g. vector.enabled=true), and score:
satellites above 15 deg at the start (truth) that the initial acquisition found and that were ever tracked,
first fix, fraction of the 10-Hz epochs after the first fix with a fix, 3D RMS (gnssrx eval).
``--reference``: the 45 dB-Hz reference recording (configs/gpssim_static_tokyo.yaml): first fix and 3D RMS
against its surveyed position.

    nice -n 19 python scripts/bench/accuracy_weak.py --scenario static33 --seeds 1 2 3
    nice -n 19 python scripts/bench/accuracy_weak.py --scenario fig8_33 --seeds 1 2 3 --set vector.enabled=true \\
        --set vector.start_s=30 --tag vector
    python scripts/bench/accuracy_weak.py --reference
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]

OUT = ROOT / "out" / "hs"
SHARED = ROOT.parent / "shared" / "data"
PY = sys.executable


def _cli(*args):
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    r = subprocess.run([PY, "-m", "receiver.cli", *args], cwd=ROOT, env=env, capture_output=True, text=True)
    if r.returncode:
        raise SystemExit(f"gnssrx {' '.join(args)} failed:\n{r.stderr}")
    return r.stdout


def score(run_h5: Path, truth_h5: Path, rate_hz: float = 10.0) -> dict:
    import h5py

    from receiver.evaluate import evaluate
    from receiver.runfile.reader import RunFile
    with h5py.File(truth_h5) as f:
        sats = f["satellites"]
        above = sorted(int(k[1:]) for k in sats if sats[k]["elevation_deg"][0] > 15.0 and sats[k]["visible"][0])
        dur = float(f["receiver"]["time_s"][-1])
    with RunFile(run_h5) as rf:
        acq = rf.acquisition()
        names = rf.channel_names()
        tracked = {rf.channel_prn(n) for n in names}
    det = acq["detected"].astype(bool)
    prn = acq["prn"]
    # the initial search is the first row of each PRN
    first = {}
    for p, d in zip(prn, det):
        first.setdefault(int(p), bool(d))
    acquired = sorted(p for p in above if first.get(p, False))
    ev = evaluate(str(run_h5), str(truth_h5))
    ttff = ev.get("ttff_s")
    n = ev.get("n_fixes", 0)
    avail = float("nan")
    if n and ttff is not None and np.isfinite(ttff):
        avail = n / max(1.0, np.floor((dur - ttff) * rate_hz) + 1)
    return {"above15": above, "acquired": acquired, "tracked_above15": sorted(p for p in above if p in tracked),
            "ttff_s": ttff, "n_fixes": n, "availability": avail, "rms3d_m": ev.get("pos_3d_rms_m"),
            "n_sats_mean": ev.get("n_sats_mean")}


def reference() -> dict:
    from receiver.runfile.reader import RunFile
    run = OUT / "ref_tokyo.h5"
    out = _cli("run", "configs/gpssim_static_tokyo.yaml", "--input", str(SHARED / "gpssim_static_tokyo.bin"),
               "-o", str(run), "--quiet")
    truth = np.array([-3959617.482, 3350136.615, 3699531.459])
    with RunFile(run) as rf:
        fx = rf.fixes()
    err = fx["ecef"] - truth
    rms = float(np.sqrt(np.mean(np.sum(err ** 2, axis=1))))
    ff = [ln for ln in out.splitlines() if ln.startswith("first fix") or ln.startswith("tracked")]
    return {"summary": ff, "n_fixes": int(len(fx)), "rms3d_m": rms}


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scenario", default="static33", help="static33, static30 or fig8_33")
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3])
    ap.add_argument("--set", dest="sets", action="append", default=[], help="receiver config override")
    ap.add_argument("--tag", default="default", help="name of this receiver variant in the output files")
    ap.add_argument("--reference", action="store_true", help="the 45 dB-Hz reference recording only")
    ap.add_argument("--tow-offset", type=float, default=0.0,
                    help="start the recording this many seconds later in the LNAV frame (time.tow_s + offset; "
                         "the scenarios start 3 s before a subframe 1)")
    ap.add_argument("--duration", type=float, default=None, help="recording length (s; default the scenario's)")
    ap.add_argument("--keep", action="store_true", help="keep the simulated recording (default: deleted "
                    "after the run when --tow-offset or --duration is given)")
    a = ap.parse_args()
    OUT.mkdir(parents=True, exist_ok=True)
    if a.reference:
        print(json.dumps(reference(), indent=1))
        return
    rows = []
    for seed in a.seeds:
        import yaml
        base = yaml.safe_load(open(ROOT / "configs" / "scenarios" / f"hs_{a.scenario}.yaml"))
        sim_sets = ["--set", f"time.seed={seed}"]
        suffix = ""
        if a.tow_offset:
            sim_sets += ["--set", f"time.tow_s={base['time']['tow_s'] + a.tow_offset}"]
            suffix += f"_o{a.tow_offset:g}"
        if a.duration:
            sim_sets += ["--set", f"time.duration_s={a.duration}"]
            suffix += f"_d{a.duration:g}"
        stem = OUT / f"{a.scenario}_s{seed}{suffix}"
        if not Path(f"{stem}.bin").exists():
            _cli("simulate", f"configs/scenarios/hs_{a.scenario}.yaml", "-o", f"{stem}.bin", *sim_sets, "--quiet")
        run = OUT / f"{a.scenario}_s{seed}{suffix}_{a.tag}.h5"
        args = ["run", "configs/default.yaml", "--input", f"{stem}.bin", "-o", str(run), "--quiet"]
        for s in a.sets:
            args += ["--set", s]
        _cli(*args)
        r = score(run, Path(f"{stem}.truth.h5"))
        r["seed"] = seed
        r["tow_offset_s"] = a.tow_offset
        rows.append(r)
        if suffix and not a.keep:
            Path(f"{stem}.bin").unlink()
        print(f"{a.scenario}{suffix} seed {seed} [{a.tag}]: "
              f"acquired {len(r['acquired'])}/{len(r['above15'])} above 15 deg "
              f"(tracked {len(r['tracked_above15'])}), first fix {r['ttff_s']}, fixes {r['n_fixes']} "
              f"(availability {r['availability']:.2f}), 3D RMS {r['rms3d_m']}, mean sats {r['n_sats_mean']}",
              flush=True)
    with open(OUT / f"{a.scenario}{suffix}_{a.tag}.json", "w") as f:
        json.dump(rows, f, indent=1, default=float)


if __name__ == "__main__":
    main()
