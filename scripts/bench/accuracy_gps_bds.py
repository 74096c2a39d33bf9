"""GPS only / BeiDou only / GPS + BeiDou on one wideband recording (issue 33: a combined fix must not be worse
than the better system alone): 3D RMS, mean east/north/up error, satellites and PDOP of each, over all its
fixes and over the epochs all three have in common.

    PYTHONPATH=. python scripts/bench/accuracy_gps_bds.py REC.bin [--out DIR] [--reuse] [-o KEY=VALUE ...]

The truth is REC.truth.h5 (gnssrx simulate, e.g. configs/scenarios/gps_bds_static_tokyo.yaml) or
REC.truth.yaml (scripts/tools/signalsim_gps_bds.py: SignalSim's IFdataGen).  Receiver: configs/gps_bds_nav.yaml
with input.format / sample_rate_hz / if_hz from the truth file (GPS at if_hz, B1I at if_hz - 14.322 MHz).
"""
from __future__ import annotations

import argparse
import os

import numpy as np

from receiver.config import read_yaml
from receiver.evaluate.systems import common_epochs, score_enu
from receiver.pipeline import run
from receiver.runfile.reader import load_run
from receiver.schema import load_receiver_config

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
B1I_OFFSET_HZ = 1575.42e6 - 1561.098e6


def truth_of(stem):
    """(truth ECEF, input overrides) of a recording REC (REC.truth.h5 or REC.truth.yaml beside it)."""
    if os.path.exists(stem + ".truth.h5"):
        import h5py
        with h5py.File(stem + ".truth.h5", "r") as t:
            return np.asarray(t["receiver"]["ecef"][0], float), 7.161e6, []
    t = read_yaml(stem + ".truth.yaml")
    return (np.asarray(t["truth"]["ecef_m"], float), float(t["if_hz"]),
            [f"input.format={t['format']}", f"input.sample_rate_hz={t['sample_rate_hz']}"])


def line(name, s):
    """One table row."""
    e, n, u = s["enu"]
    return (f"| {name:13s} | {s['n']:4d} | {s['rms']:6.3f} | {e:+6.3f} | {n:+6.3f} | {u:+6.3f} | {s['sats']:5.1f} "
            f"| {s['pdop']:5.2f} |")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("recording")
    ap.add_argument("--out", default=None, help="directory of the run files (default: beside the recording)")
    ap.add_argument("--reuse", action="store_true", help="score run files already there instead of running")
    ap.add_argument("--cases", default="gb,g,c", help="comma list of gb (GPS + BeiDou), g (GPS), c (BeiDou)")
    ap.add_argument("--tag", default="", help="suffix of the run files' names")
    ap.add_argument("-o", dest="overrides", action="append", default=[], help="receiver config override")
    a = ap.parse_args(argv)
    stem = a.recording[:-4] if a.recording.endswith(".bin") else a.recording
    out = a.out or os.path.dirname(os.path.abspath(a.recording))
    x_true, if_gps, inp = truth_of(stem)
    cases = {"gb": ("GPS + BeiDou", ["signals=[gps_l1ca, bds_b1i]", f"input.if_hz={if_gps}"]),
             "g": ("GPS only", ["signals=[gps_l1ca]", f"input.if_hz={if_gps}"]),
             "c": ("BeiDou only", ["signals=[bds_b1i]", f"input.if_hz={if_gps - B1I_OFFSET_HZ}",
                                   f"acquisition.prns={list(range(1, 38))}"])}
    fixes = {}
    for key in a.cases.split(","):
        h5 = os.path.join(out, f"gpsbds_{key}{a.tag}.h5")
        if not (a.reuse and os.path.exists(h5)):
            cfg = load_receiver_config(os.path.join(ROOT, "configs/gps_bds_nav.yaml"),
                                       [f"input.path={a.recording}", f"output.path={h5}"] + inp + cases[key][1]
                                       + a.overrides)
            run(cfg, quiet=True, log=lambda *x: None)
        fixes[key] = load_run(h5).fixes
    common = common_epochs(*fixes.values())
    head = "| case          | fixes | 3D RMS m | mean E m | mean N m | mean U m | sats | PDOP |"
    for title, keep in (("all fixes", None), (f"{len(common)} common epochs", common)):
        print(f"\n{title}\n{head}\n|---|---|---|---|---|---|---|---|")
        for key, fx in fixes.items():
            print(line(cases[key][0], score_enu(fx, x_true, keep)))


if __name__ == "__main__":
    main()
