#!/usr/bin/env python3
"""Draw the diagrams of the documentation site into docs/img/ (small PNGs, committed).

    python scripts/tools/docs_figures.py

pipeline.png        the receiver's stages and what flows between them
channel_states.png  a tracking channel's life: acquisition, pull-in, tracking, loss, re-acquisition
acquisition.png     the code-phase x Doppler search of one satellite of a real recording (drawn only when
                    ../shared/data/real/ is beside the checkout; otherwise the committed picture stays)
"""
import os
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.patches import FancyArrowPatch, FancyBboxPatch  # noqa: E402

#: the checkout: the first parent holding pyproject.toml (the script may live in scripts/ or a subfolder)
ROOT = next(p for p in Path(__file__).resolve().parents if (p / "pyproject.toml").exists())
OUT = ROOT / "docs" / "img"


def _box(ax, x, y, w, h, title, lines=(), color="#dfe6f7"):
    ax.add_patch(FancyBboxPatch((x, y), w, h, boxstyle="round,pad=0.02,rounding_size=0.08",
                                fc=color, ec="#3f51b5", lw=1.2))
    ax.text(x + w / 2, y + h - 0.22, title, ha="center", va="top", fontsize=10.5, weight="bold")
    for i, t in enumerate(lines):
        ax.text(x + w / 2, y + h - 0.62 - 0.3 * i, t, ha="center", va="top", fontsize=8.2)


def _arrow(ax, a, b, text=None, dy=0.12, rad=0.0):
    ax.add_patch(FancyArrowPatch(a, b, arrowstyle="-|>", mutation_scale=13, lw=1.2, color="#333",
                                 connectionstyle=f"arc3,rad={rad}"))
    if text:
        ax.text((a[0] + b[0]) / 2, (a[1] + b[1]) / 2 + dy, text, ha="center", va="bottom", fontsize=7.8,
                style="italic", color="#333")


def pipeline():
    fig, ax = plt.subplots(figsize=(9.5, 3.7), dpi=120)
    ax.set_xlim(0, 22)
    ax.set_ylim(0, 7.6)
    ax.axis("off")
    w, h, y = 2.9, 2.5, 4.2
    xs = [0.05, 3.85, 7.65, 11.45, 15.25, 19.05]
    boxes = [("Recording", ["IF samples", "+ metadata"], "#eeeeee"),
             ("Input", ["resample,", "DC, notches"], None),
             ("Acquisition", ["FFT search,", "integrity"], None),
             ("Tracking", ["scalar loops,", "vector loops"], None),
             ("Navigation", ["messages,", "PVT"], None),
             ("Run file", ["HDF5 →", "RINEX, NMEA"], "#e3f2e1")]
    for x, (t, lines, c) in zip(xs, boxes):
        ax.add_patch(FancyBboxPatch((x, y), w, h, boxstyle="round,pad=0.02,rounding_size=0.1",
                                    fc=c or "#dfe6f7", ec="#3f51b5", lw=1.3))
        ax.text(x + w / 2, y + h - 0.3, t, ha="center", va="top", fontsize=12, weight="bold")
        for i, line in enumerate(lines):
            ax.text(x + w / 2, y + h - 1.05 - 0.55 * i, line, ha="center", va="top", fontsize=10)
    labels = ["samples", "stream", "detections", "records", "fixes"]
    for i in range(5):
        a, b = (xs[i] + w, y + h / 2), (xs[i + 1], y + h / 2)
        _arrow(ax, a, b)
        ax.text((a[0] + b[0]) / 2, y - 0.15, labels[i], ha="center", va="top", fontsize=9, style="italic",
                color="#333")
    cx, cw, ch = 9.3, 4.6, 2.0
    ax.add_patch(FancyBboxPatch((cx, 0.25), cw, ch, boxstyle="round,pad=0.02,rounding_size=0.1",
                                fc="#fdf1dc", ec="#3f51b5", lw=1.3))
    ax.text(cx + cw / 2, 0.25 + ch - 0.3, "Channel manager", ha="center", va="top", fontsize=12, weight="bold")
    ax.text(cx + cw / 2, 0.25 + ch - 1.05, "losses, re-acquisition", ha="center", va="top", fontsize=10)
    _arrow(ax, (11.45 + w / 2, y), (12.3, 0.25 + ch))
    _arrow(ax, (cx, 1.25), (7.65 + w / 2, y), rad=-0.25)
    _arrow(ax, (15.25 + 0.4, y), (cx + cw, 1.4), rad=0.2)
    ax.text(11.0, 7.5, "every 0.5-s chunk: read → (acquire) → track → manage channels → navigate → write",
            ha="center", va="top", fontsize=10)
    fig.tight_layout()
    fig.savefig(OUT / "pipeline.png")
    plt.close(fig)


def channel_states():
    fig, ax = plt.subplots(figsize=(10, 3.4), dpi=110)
    ax.set_xlim(0, 17.3)
    ax.set_ylim(0, 6.0)
    ax.axis("off")
    w, h = 3.5, 1.9
    pos = {"search": (0.2, 3.8), "pull-in": (4.65, 3.8), "track": (9.1, 3.8), "bit sync": (13.55, 3.8),
           "lost": (13.55, 0.5), "re-acquire": (6.9, 0.5)}
    info = {"search": ["cold FFT search", "(acquisition)"], "pull-in": ["FLL-assisted PLL,", "wide DLL, 300 ms"],
            "track": ["PLL + DLL, 1 ms,", "C/N0, lock"], "bit sync": ["data-bit edges known,", "up to 20 ms coherent"],
            "lost": ["presence test or", "lock detectors"],
            "re-acquire": ["narrow search around", "the predicted code, Doppler"]}
    for k, (x, y) in pos.items():
        _box(ax, x, y, w, h, k, info[k], "#fdf1dc" if k in ("lost", "re-acquire") else "#dfe6f7")

    def edge(a, b, text, side="h", rad=0.0):
        (xa, ya), (xb, yb) = pos[a], pos[b]
        if side == "h":
            _arrow(ax, (xa + w, ya + h / 2), (xb, yb + h / 2), text, rad=rad)
        else:
            _arrow(ax, (xa + w / 2, ya), (xb + w / 2, yb + h), text, rad=rad)
    edge("search", "pull-in", "detected")
    edge("pull-in", "track", "settled")
    edge("track", "bit sync", "edges found")
    edge("bit sync", "lost", "", side="v")
    ax.text(pos["lost"][0] + w / 2 + 0.15, 3.1, "signal gone\n(~20-40 ms)", fontsize=7.8, style="italic", va="center")
    _arrow(ax, (pos["lost"][0], 1.45), (pos["re-acquire"][0] + w, 1.45), "after 0.15 s, every 0.125 s")
    _arrow(ax, (pos["re-acquire"][0] + w / 2, 2.4), (pos["pull-in"][0] + w / 2 + 0.5, 3.8), "found: 40-ms pull-in",
           dy=0.0)
    _arrow(ax, (pos["re-acquire"][0], 1.45), (pos["search"][0] + w / 2, 3.8), "outage > max_age_s:\ncold search",
           dy=0.0, rad=-0.3)
    fig.tight_layout()
    fig.savefig(OUT / "channel_states.png")
    plt.close(fig)


#: the shared data beside the checkout (GNSSRX_SHARED_DIR overrides), as in tests/system/test_docs_tutorials.py
SHARED = Path(os.environ.get("GNSSRX_SHARED_DIR", ROOT.parent / "shared"))
REAL = SHARED / "data" / "real" / "pocketsdr_L1_20211202_084700_4MHz_IQ.bin"


def acquisition_grid(prn: int = 26, fs: float = 4e6, coherent_ms: int = 4, noncoherent: int = 10):
    """The search grid of PRN 26 in the PocketSDR sample (4 MS/s int8 I/Q, Q inverted): coherent
    4 ms x 10 non-coherent, +/-5 kHz in 125 Hz bins, each row over its median (as the detector sees it)."""
    import numpy as np

    from receiver.gnss.signals import GPS_L1CA, ca_code, sample_code
    if not REAL.exists():
        return False
    raw = np.fromfile(REAL, dtype=np.int8, count=2 * int(fs * 1e-3 * coherent_ms * noncoherent))
    x = (raw[1::2] + 1j * raw[0::2]).astype(np.complex64)          # I/Q swapped
    n = int(fs * 1e-3 * coherent_ms)
    t = np.arange(n) / fs
    code = sample_code(ca_code(prn), GPS_L1CA.chip_rate, fs, n)
    cf = np.conj(np.fft.fft(code))
    dopplers = np.arange(-5000.0, 5000.0 + 1, 125.0)
    power = np.zeros((len(dopplers), int(fs * 1e-3)))
    for i, f in enumerate(dopplers):
        wipe = np.exp(-2j * np.pi * f * t)
        for k in range(noncoherent):
            c = np.fft.ifft(np.fft.fft(x[k * n:(k + 1) * n] * wipe) * cf)
            p = np.abs(c) ** 2
            power[i] += p[: power.shape[1]]                      # one code period of lags
    power /= np.median(power, axis=1, keepdims=True)
    chips = np.arange(power.shape[1]) * GPS_L1CA.chip_rate / fs
    di, si = np.unravel_index(np.argmax(power), power.shape)
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(9.5, 3.2), dpi=110, gridspec_kw={"width_ratios": [2.2, 1]})
    a1.plot(chips, power[di], lw=0.7, color="#3f51b5")
    a1.set_xlabel("code phase of the replica (chips)")
    a1.set_ylabel("power / row median")
    a1.set_title(f"Doppler row {dopplers[di]:+.0f} Hz: the correlation peak over all code phases", fontsize=9.5)
    a1.set_xlim(0, 1023)
    a2.plot(dopplers / 1e3, power[:, si], ".-", lw=0.8, ms=3, color="#c62828")
    a2.set_xlabel("Doppler (kHz)")
    a2.set_title("at the peak's code phase, over Doppler", fontsize=9.5)
    for ax in (a1, a2):
        ax.grid(alpha=0.3)
    fig.suptitle(f"Acquisition of G{prn:02d} in the PocketSDR L1 sample ({coherent_ms} ms coherent x {noncoherent})",
                 fontsize=10.5)
    fig.tight_layout()
    fig.savefig(OUT / "acquisition.png")
    plt.close(fig)
    return True


def main():
    OUT.mkdir(parents=True, exist_ok=True)
    pipeline()
    channel_states()
    made = ["pipeline.png", "channel_states.png"]
    if acquisition_grid():
        made.append("acquisition.png")
    for p in made:
        print(f"wrote {OUT / p} ({(OUT / p).stat().st_size // 1024} KB)")


if __name__ == "__main__":
    main()
