"""Per-satellite LNAV timeline of a run file (issue 17: what sets the first-fix time at low C/N0).

For every stored channel: the start of tracking, bit synchronisation, frame sync, each subframe (id, the
receiver time its last bit arrived, words corrected / failed) and the complete ephemeris, by replaying the
channel's 20-ms prompt sums through the LNAV decoder bit by bit; then the first fix of the run.

    python scripts/tools/hs_timeline.py out/hs/static33_s1_default.h5 [--subframes]
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]

from receiver.gnss import lnav  # noqa: E402
from receiver.runfile.reader import RunFile  # noqa: E402
from receiver.runfile.record import STATE_BIT_SYNC  # noqa: E402


def _bits(ch):
    """(bit index, soft value, receiver time of the bit's end) of the bit-synchronised epochs, whole bits only."""
    sync = ch["state"] == STATE_BIT_SYNC
    if not sync.any():
        return None
    cp = ch["code_period"][sync]
    ms = ch["integration_ms"][sync].astype(int)
    full = ms == 20
    if full.any():
        offset = int(np.bincount(cp[full] % 20, minlength=20).argmax())
    else:
        pi = ch["prompt_i"][sync]
        change = np.nonzero(np.sign(pi[1:]) * np.sign(pi[:-1]) < 0)[0] + 1
        offset = int(np.bincount(cp[change] % 20, minlength=20).argmax()) if len(change) else 0
    p = ch["prompt1_i"][sync].astype(float) + ch["prompt2_i"][sync].astype(float)
    t = ch["time_s"][sync] + ms * 1e-3
    bit = (cp - offset) // 20
    ub, first, inv = np.unique(bit, return_index=True, return_inverse=True)
    sums = np.bincount(inv, weights=p)
    count = np.bincount(inv, weights=ms)
    tend = np.zeros(len(ub))
    np.maximum.at(tend, inv, t)
    ok = count == 20
    return ub[ok], sums[ok], tend[ok]


def timeline(path, verbose=False):
    seen = []
    orig = lnav._decode_subframe_bits

    def spy(b, correct=False):
        out = orig(b, correct)
        if correct:
            seen.append((out[1].count(False), out[2]))
        return out

    lnav._decode_subframe_bits = spy
    rows = []
    try:
        with RunFile(path) as rf:
            fx = rf.fixes()
            ttff = float(fx["time_s"][0]) if len(fx) else None
            for name in rf.channel_names():
                ch = rf.channel(name, ("state", "code_period", "prompt1_i", "prompt2_i", "prompt_i",
                                       "integration_ms", "time_s"))
                prn = rf.channel_prn(name)
                r = {"prn": prn, "t_track": float(ch["time_s"][0]) if len(ch["time_s"]) else None,
                     "t_bitsync": None, "t_sync": None, "t_eph": None, "sf": []}
                b = _bits(ch)
                if b is None:
                    rows.append(r)
                    continue
                idx, sums, tend = b
                r["t_bitsync"] = float(ch["time_s"][np.argmax(ch["state"] == STATE_BIT_SYNC)])
                dec = lnav.LnavDecoder(prn, week_hint=2300)
                for i in range(len(idx)):
                    seen.clear()
                    evs = dec.feed(sums[i:i + 1], int(idx[i]))
                    if dec.synced and r["t_sync"] is None:
                        r["t_sync"] = float(tend[i])
                    sfev = [e for e in evs if isinstance(e, lnav.SubframeEvent)]
                    for k, (nbad, ncorr) in enumerate(seen):
                        sid = sfev[k].subframe_id if k < len(sfev) else 0
                        r["sf"].append((round(float(tend[i]), 2), sid, ncorr, nbad))
                    for e in evs:
                        if isinstance(e, lnav.EphemerisEvent) and r["t_eph"] is None:
                            r["t_eph"] = float(tend[i])
                r["held"] = dec.ephemerides_held
                rows.append(r)
    finally:
        lnav._decode_subframe_bits = orig
    return rows, ttff


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("run", nargs="+")
    ap.add_argument("--subframes", action="store_true", help="list every subframe")
    a = ap.parse_args()
    for path in a.run:
        rows, ttff = timeline(path)
        print(f"== {path}: first fix {ttff}")
        print("  PRN  track  bitsync  framesync  ephem  subframes(id:corrected/failed words)")
        f = lambda v: "   -  " if v is None else f"{v:6.2f}"  # noqa: E731
        for r in rows:
            sfs = " ".join(f"{sid}:{c}/{n}" for _, sid, c, n in r["sf"][:12])
            print(f"  G{r['prn']:02d} {f(r['t_track'])} {f(r['t_bitsync'])} {f(r['t_sync'])} {f(r['t_eph'])}  "
                  f"{sfs if a.subframes else (sfs[:60])}")
        te = sorted(r["t_eph"] for r in rows if r["t_eph"] is not None)
        print(f"  4th ephemeris at {te[3] if len(te) >= 4 else None}; ephemerides at {[round(x, 1) for x in te]}")


if __name__ == "__main__":
    main()
