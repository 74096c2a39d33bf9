"""What a receiver run returns and ``gnssrx run`` prints: :class:`RunSummary` (receiver.pipeline.run)."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .gnss.satid import sat_label
from .runfile.record import IONO_BROADCAST, IONO_FALLBACK, IONO_NONE


@dataclass
class RunSummary:
    """What :func:`run` returns (and ``gnssrx run`` prints): the output path, the signal duration and wall
    time, the satellites tracked with their mean C/N0, the number of fixes and the first fix time, the
    mean position and its east/north/up scatter, and counters (parity failures, re-acquisitions, false
    locks restarted, non-finite samples, fixes per ionospheric parameter set)."""
    output: str
    duration_s: float
    wall_s: float
    tracked: list = field(default_factory=list)
    mean_cn0: dict = field(default_factory=dict)
    n_fixes: int = 0
    first_fix_s: float | None = None
    mean_llh: tuple | None = None
    scatter_m: tuple | None = None     # (east, north, up) standard deviation
    parity_failures: int = 0
    reacquisitions: int = 0
    false_locks: dict = field(default_factory=dict)     # sat key -> carrier false locks restarted
    nonfinite_samples: int = 0         # NaN/Inf input samples replaced by zeros
    system: str = "G"                  # RINEX letter of the signal (labels: G05, J01, C12)
    # fixes per FIX_DTYPE iono_params code, and the first fix (s after the first sample) with broadcast ones
    iono_counts: dict = field(default_factory=dict)
    iono_broadcast_from_s: float | None = None
    notes: list = field(default_factory=list)   # input conditioning / acquisition lines

    def iono_text(self) -> str:
        """Which Klobuchar parameters the fixes used (FIX_DTYPE iono_params)."""
        n = self.iono_counts
        before = [w for k, w in ((IONO_FALLBACK, "fallback set"), (IONO_NONE, "no correction")) if n.get(k)]
        if n.get(IONO_BROADCAST):
            if not before:
                return "broadcast parameters (every fix)"
            return f"broadcast parameters from {self.iono_broadcast_from_s:.1f} s, {' / '.join(before)} before"
        if n.get(IONO_FALLBACK):
            return "fallback set (no broadcast parameters known; navigation.klobuchar_fallback)"
        return "no correction (navigation.ionosphere none, or no parameters known)"

    @property
    def realtime_factor(self) -> float:
        """Seconds of signal processed per second of wall-clock time (inf for a zero wall time)."""
        return self.duration_s / self.wall_s if self.wall_s > 0 else float("inf")

    def text(self) -> str:
        """The run summary as text (one item per line), as ``gnssrx run`` prints it."""
        lines = [f"output          {self.output}",
                 f"signal          {self.duration_s:.1f} s processed in {self.wall_s:.1f} s "
                 f"(real-time factor {self.realtime_factor:.1f}x)",
                 f"tracked         {len(self.tracked)} satellites: "
                 + " ".join(f"{sat_label(p, self.system)}({self.mean_cn0[p]:.1f})" for p in self.tracked)]
        if self.mean_cn0:
            lines.append(f"mean C/N0       {np.mean(list(self.mean_cn0.values())):.1f} dB-Hz")
        if self.reacquisitions:
            lines.append(f"re-acquisitions {self.reacquisitions} (signal lost and found again)")
        if self.false_locks:
            lines.append("false locks     " + " ".join(f"{sat_label(p, self.system)} x{n}" for p, n in
                                                      sorted(self.false_locks.items()))
                         + " (carrier off the code's Doppler: channel restarted there)")
        if self.n_fixes:
            lat, lon, h = self.mean_llh
            lines += [f"first fix       {self.first_fix_s:.2f} s after the first sample",
                      f"fixes           {self.n_fixes}",
                      f"mean position   lat {lat:.7f} lon {lon:.7f} h {h:.2f} m",
                      "scatter (1 sd)  E {:.2f} N {:.2f} U {:.2f} m".format(*self.scatter_m)]
        else:
            lines.append("fixes           none")
        if self.n_fixes and self.iono_counts:
            lines.append(f"ionosphere      {self.iono_text()}")
        if self.nonfinite_samples:
            lines.append(f"input           {self.nonfinite_samples} non-finite samples replaced by zeros")
        return "\n".join(lines + self.notes)
