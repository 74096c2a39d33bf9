"""Signal blockage of the simulator: which satellite carries a signal when (``blockage.*`` scenario keys).

Four mechanisms, applied on top of the elevation mask (times are receiver seconds since the first sample,
intervals half-open ``[start_s, end_s)``):

``outages``
    Per-satellite windows ``{prn, start_s, end_s}``; ``prn: all`` blocks every satellite (same as ``total``).
``total``
    Windows ``{start_s, end_s}`` in which no satellite carries a signal (bridges, tunnels).
``random`` (urban canyon)
    Per-satellite random blockages inside ``[start_s, end_s)``: each satellite alternates between a visible
    gap and a blockage.  Blockage lengths are uniform (``distribution: uniform``) or log-uniform
    (``loguniform``: short blockages -- poles, trees -- more common than long ones -- buildings) in
    ``[min_duration_s, max_duration_s]``; visible gaps are
    ``min_duration_s + m * E`` with E unit-exponential, and the first visible gap of each satellite is a
    uniform fraction of one such gap.  The mean gap scale ``m`` is calibrated (bisection with the random
    draws held fixed) so that at least ``min_visible`` satellites carry a signal -- after the elevation
    mask, the ``outages`` and the ``total`` windows -- during ``target_fraction`` of the window, measured on
    a 10 ms grid.  The draws come from ``SeedSequence([seed, 4, prn])`` (``seed``: ``random.seed``, or the
    scenario's ``time.seed`` when empty), so the same scenario gives the same pattern.
``visible_count``
    Schedule ``[t_s, n]``: from ``t_s`` on at most n satellites carry a signal (lowest elevations dropped
    first); applied last and not part of the random calibration.

:meth:`Blockage.write` records every realised window in the truth file's ``/blockage`` group (datasets
``prn`` (0 = every satellite), ``start_s``, ``end_s``, ``kind`` (0 outage, 1 total, 2 random) and the
random pattern's parameters as attributes), so evaluation knows what the receiver faced.
"""
from __future__ import annotations

import math

import numpy as np

from ..errors import UserError

KIND_OUTAGE, KIND_TOTAL, KIND_RANDOM = 0, 1, 2
KIND_MAPPING = "0=outage,1=total,2=random"
CAL_STEP_S = 0.01            # grid of the random-blockage calibration


def _window(item, key, allowed, need_prn=False):
    if not isinstance(item, dict) or set(item) - allowed or (need_prn and "prn" not in item):
        fields = ", ".join(sorted(allowed, key=("prn", "start_s", "end_s").index))
        raise UserError(f"config key '{key}' must be a mapping {{{fields}}}")
    try:
        a, b = float(item.get("start_s", 0.0)), float(item.get("end_s", math.inf))
    except (TypeError, ValueError):
        raise UserError(f"config key '{key}' must hold numbers") from None
    if not b > a:
        raise UserError(f"config key '{key}': end_s must be after start_s")
    return a, b


def parse_outages(raw):
    """``blockage.outages`` -> ({prn: [(start, end), ...]}, [(start, end) of the ``prn: all`` entries])."""
    per, every = {}, []
    for i, item in enumerate(raw or []):
        key = f"blockage.outages[{i}]"
        a, b = _window(item, key, {"prn", "start_s", "end_s"}, need_prn=True)
        prn = item["prn"]
        if isinstance(prn, str) and prn.strip().lower() == "all":
            every.append((a, b))
            continue
        try:
            if isinstance(prn, bool):
                raise TypeError
            prn = int(prn)
        except (TypeError, ValueError):
            raise UserError(f"config key '{key}.prn' must be a PRN number or 'all'") from None
        per.setdefault(prn, []).append((a, b))
    return per, every


def parse_total(raw):
    """``blockage.total`` -> [(start_s, end_s), ...]; a malformed entry is a one-line UserError."""
    return [_window(item, f"blockage.total[{i}]", {"start_s", "end_s"}) for i, item in enumerate(raw or [])]


def parse_visible_count(raw):
    """``blockage.visible_count`` -> [(t_s, n), ...] sorted by time; a malformed entry is a one-line UserError."""
    rows = []
    for i, item in enumerate(raw or []):
        try:
            t, n = item
            rows.append((float(t), int(n)))
        except (TypeError, ValueError):
            raise UserError(f"config key 'blockage.visible_count[{i}]' must be [t_s, n]") from None
    rows.sort()
    return rows


def _blocked(t, starts, ends):
    """Boolean mask of the times t inside one of the sorted, non-overlapping intervals [starts, ends)."""
    if len(starts) == 0:
        return np.zeros(np.shape(t), bool)
    k = np.searchsorted(starts, t, side="right") - 1
    return (k >= 0) & (t < np.asarray(ends)[np.maximum(k, 0)])


class RandomBlockage:
    """Urban-canyon pattern (see the module docstring): per-PRN blockage intervals inside [t0, t1)."""

    def __init__(self, prns, t0, t1, min_s, max_s, seed, distribution="uniform"):
        self.prns, self.t0, self.t1 = list(prns), t0, t1
        self.min_s, self.max_s = min_s, max_s
        n = int(math.ceil((t1 - t0) / (2.0 * min_s))) + 4     # every cycle lasts >= 2 min_s: enough cycles
        self._draws = {}
        for p in self.prns:
            rng = np.random.default_rng(np.random.SeedSequence([seed, 4, p]))
            u_block = rng.random(n)
            e_gap = rng.standard_exponential(n)
            first = rng.random()
            block = min_s * (max_s / min_s) ** u_block if distribution == "loguniform" \
                else min_s + (max_s - min_s) * u_block
            self._draws[p] = (block, e_gap, first)
        self.mean_block_s = (((max_s - min_s) / math.log(max_s / min_s) if max_s > min_s else min_s)
                             if distribution == "loguniform" else 0.5 * (min_s + max_s))
        self.gap_scale_s = math.nan
        self.intervals = {p: (np.zeros(0), np.zeros(0)) for p in self.prns}

    def realise(self, gap_scale_s):
        """Blockage intervals {prn: (starts, ends)} for a mean-gap scale m (s)."""
        out = {}
        for p in self.prns:
            block, e_gap, first = self._draws[p]
            gaps = self.min_s + gap_scale_s * e_gap
            gaps[0] *= first
            # cycle k: visible gap gaps[k], then blockage block[k]
            ends_of_gaps = self.t0 + np.cumsum(gaps + block) - block
            starts = ends_of_gaps
            ends = np.minimum(starts + block, self.t1)
            keep = starts < self.t1
            out[p] = (starts[keep], ends[keep])
        return out

    def calibrate(self, base_visible, t_grid, min_visible, target):
        """Choose the gap scale so that >= min_visible satellites are visible during ``target`` of t_grid.

        base_visible: (n_prn, n_t) bool, visibility without the random blockage on t_grid.
        Returns the realised fraction."""
        mean_block = self.mean_block_s

        def frac(scale):
            iv = self.realise(scale)
            vis = base_visible.copy()
            for i, p in enumerate(self.prns):
                vis[i] &= ~_blocked(t_grid, *iv[p])
            return float(np.mean(vis.sum(axis=0) >= min_visible)), iv

        lo, hi = math.log(1e-3 * mean_block), math.log(1e3 * mean_block)
        best = None
        for _ in range(40):
            mid = 0.5 * (lo + hi)
            f, iv = frac(math.exp(mid))
            if best is None or abs(f - target) < abs(best[0] - target):
                best = (f, math.exp(mid), iv)
            if abs(f - target) < 2e-3:
                break
            if f < target:
                lo = mid
            else:
                hi = mid
        self.fraction, self.gap_scale_s, self.intervals = best
        return self.fraction


class Blockage:
    """Visibility of every simulated satellite (see the module docstring).

    cfg: the scenario's ``blockage`` section; prns: the simulated PRNs; duration_s: recording length;
    seed: the scenario seed; elevations: (t (s), {prn: elevation deg at t}) on a coarse grid covering the
    run (used to calibrate the random pattern); mask_deg: the elevation mask.
    """

    def __init__(self, cfg, prns, duration_s, seed, elevations, mask_deg):
        self.prns = list(prns)
        self.outages, every = parse_outages(cfg.outages)
        self.total = sorted(parse_total(cfg.total) + every)
        self.vis_count = parse_visible_count(cfg.visible_count)
        self.random = None
        r = cfg.random
        if r.enabled:
            t0 = r.start_s
            t1 = duration_s if r.end_s is None else min(r.end_s, duration_s)
            if not t1 > t0:
                raise UserError("config key 'blockage.random.end_s' must be after blockage.random.start_s "
                                "(and start_s before the end of the recording)")
            if r.max_duration_s < r.min_duration_s:
                raise UserError("config key 'blockage.random.max_duration_s' must be >= min_duration_s")
            self.random = RandomBlockage(self.prns, t0, t1, r.min_duration_s, r.max_duration_s,
                                         seed if r.seed is None else r.seed, r.distribution)
            self.random_cfg = r
            t_grid = np.arange(t0, t1, CAL_STEP_S)
            ts, el = elevations
            base = np.array([np.interp(t_grid, ts, el[p]) >= mask_deg for p in self.prns]).reshape(
                len(self.prns), t_grid.size)
            base &= self._fixed(t_grid)
            if int(base.sum(axis=0).max(initial=0)) < r.min_visible:
                raise UserError(f"config key 'blockage.random.min_visible': only {int(base.sum(axis=0).max())}"
                                " satellites are above the elevation mask in the random-blockage window")
            self.random.calibrate(base, t_grid, r.min_visible, r.target_fraction)

    def _fixed(self, t):
        """(n_prn, n_t) visibility under the outages and total windows alone."""
        vis = np.ones((len(self.prns), np.size(t)), bool)
        for a, b in self.total:
            vis &= ~((t >= a) & (t < b))[None, :]
        for i, p in enumerate(self.prns):
            for a, b in self.outages.get(p, ()):
                vis[i] &= ~((t >= a) & (t < b))
        return vis

    def visibility(self, t_rel, el_deg, mask_deg):
        """(n_prn, n_t) bool: satellite i carries a signal at receiver time t_rel (el_deg: (n_prn, n_t))."""
        visible = (el_deg >= mask_deg) & self._fixed(t_rel)
        if self.random is not None:
            for i, p in enumerate(self.prns):
                visible[i] &= ~_blocked(t_rel, *self.random.intervals[p])
        if self.vis_count:
            counts = np.full(t_rel.shape, len(self.prns))
            for ts, nmax in self.vis_count:
                counts[t_rel >= ts] = nmax
            key = np.where(visible, el_deg, -np.inf)
            order = np.argsort(-key, axis=0, kind="stable")
            rank = np.empty_like(order)
            np.put_along_axis(rank, order, np.broadcast_to(np.arange(len(self.prns))[:, None], order.shape),
                              axis=0)
            visible &= rank < counts[None, :]
        return visible

    def table(self):
        """Every configured / realised window: (prn, start_s, end_s, kind) arrays, sorted by start."""
        rows = [(0, a, b, KIND_TOTAL) for a, b in self.total]
        rows += [(p, a, b, KIND_OUTAGE) for p, w in self.outages.items() if p in self.prns for a, b in w]
        if self.random is not None:
            for p, (s, e) in self.random.intervals.items():
                rows += [(p, float(a), float(b), KIND_RANDOM) for a, b in zip(s, e)]
        rows.sort(key=lambda r: (r[1], r[0]))
        cols = list(zip(*rows)) if rows else ([], [], [], [])
        return (np.array(cols[0], np.int32), np.array(cols[1], float), np.array(cols[2], float),
                np.array(cols[3], np.uint8))

    def write(self, h5file):
        """The ``/blockage`` group of the truth file."""
        prn, a, b, kind = self.table()
        g = h5file.create_group("blockage")
        g.create_dataset("prn", data=prn)
        g.create_dataset("start_s", data=a)
        g.create_dataset("end_s", data=b)
        g.create_dataset("kind", data=kind)
        g.attrs["kind_mapping"] = KIND_MAPPING
        g.attrs["time_reference"] = "receiver seconds since the first sample (truth time_s); prn 0 = all"
        if self.random is not None:
            r = self.random_cfg
            g.attrs.update({"random_start_s": self.random.t0, "random_end_s": self.random.t1,
                            "random_min_visible": r.min_visible, "random_target_fraction": r.target_fraction,
                            "random_fraction": self.random.fraction,
                            "random_gap_scale_s": self.random.gap_scale_s,
                            "random_min_duration_s": r.min_duration_s, "random_max_duration_s": r.max_duration_s,
                            "random_distribution": r.distribution})
