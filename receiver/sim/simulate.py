"""Truth-tagged IF simulator (GPS L1 C/A, QZSS, BeiDou B1I): ``simulate(scenario, out_path)``.

Time conventions (see also docs/how-it-works/simulator.md and the truth file attributes)
-----------------------------------------------------------------------------------
* Receiver clock = sample counter: the receiver time of sample n is ``T = tow_s + n / fs`` (fs nominal).
  ``time_s`` in the truth file is ``n / fs``.
* Clock bias ``b = T - t`` (t true GPS time), drift ``y = db/dt`` = the oscillator's fractional frequency
  error: the true sample interval is ``1 / (fs (1 + y))`` and the local oscillator runs at
  ``(f_L1 - IF)(1 + y)``, so every carrier appears shifted by about ``-y f_L1``.
* A satellite signal received at true time t left the satellite at t - tau, where tau solves
  ``c tau = |r_rx(t) - R_z(omega_e tau) r_sat(t - tau)| + I + T`` (Sagnac by rotating the satellite into
  the ECEF frame at reception; I, T ionospheric and tropospheric group delays, metres).  The code it
  carries is the satellite clock time ``t - tau + dt_sv`` (dt_sv: af0.. + relativistic - TGD, as
  :func:`receiver.gnss.ephemeris.sat_state`).  The carrier arrives with the ionosphere ADVANCED:
  its phase is that of satellite time ``t - tau_c + dt_sv`` with ``c tau_c = rho - I + T``.
* Hence with D_code = b + tau - dt_sv and D_carr = b + tau_c - dt_sv (seconds, functions of T):
    pseudorange_m        = c D_code   (= c (receiver clock reading - satellite transmit time))
    code phase (chips)   = 1.023e6 (T - D_code) mod 1023
    carrier phase (cyc)  = -f_L1 D_carr + phi_scint / 2 pi      (the IF term IF*T excluded)
    sample phase         = IF (T - tow_s) + carrier phase       signal = amp code data exp(+j 2 pi phase)
    doppler_hz           = d(carrier phase)/dT  (observed frequency - nominal carrier - IF; >0 approaching)
  LNAV bits change where the satellite time of the received code crosses a multiple of 20 ms; subframe 1
  of each frame starts at a satellite TOW multiple of 30 s.
* C/N0: complex formats: C/N0 = A^2 fs / (2 sigma^2) (sigma: noise std per component);
  real formats: C/N0 = (A^2/2) / (2 sigma^2 / fs).

Generation streams in blocks (``output.block_s``): the propagation geometry is computed every 10 ms of
receiver time (on the truth rows) and carried to a 1 ms grid by cubic Hermite interpolation of the delays
and their exact rates; receiver clock, scintillation and visibility are evaluated on the 1 ms grid; the

The module holds the entry point, the time base and the block synthesis; the set-up of the scenario's
satellites and what they transmit is receiver.sim.sources, the propagation geometry receiver.sim.geometry,
the output files receiver.sim.outputs and the compiled synthesis receiver.sim.kernel.
"""
from __future__ import annotations

import math
import os
from types import SimpleNamespace

import numpy as np

from .. import interrupt
from .. import __version__
from ..errors import UserError
from ..estimation.interpolation import hermite
from ..gnss.geodesy import ecef2lla
from ..gnss.satid import MIXED, split_key
from ..gnss.signals import C_LIGHT
from ..gnss.signals_bds import data_signs
from ..safeio import TMP_SUFFIX, OutputLock, check_output, write_error_message
from ..source.io import Encoder, is_complex
from .blockage import Blockage
from .clock import ClockGenerator
from .geometry import SatelliteTrack, satellite_geometry, scan_elevations
from .impairments import Impairments
from .kernel import quantize_fast, synth_block
from .outputs import TruthWriter, files_read, output_paths, remove_files, write_companions
from .scenario import clock_h, load_scenario, noise_sigma, resolve_path
from .sources import (Cn0Model, Overlap, broadcast_iono, chosen_ephemerides, load_ephemerides, multi_gal_content,
                      nav_sources, scintillation_streams, select_signals)
from .trajectory import CsvTrajectory, make_trajectory

GRID_S = 1e-3                     # truth / interpolation grid of the kernel (receiver time)
NODE_STEPS = 10                   # geometry computed every 10 grid steps (10 ms), Hermite in between


@interrupt.deferred()     # SIGINT/SIGTERM only set a flag, checked once per block
def simulate(scenario, out_path, overrides=(), progress=True) -> dict:
    """Simulate a scenario (YAML path, dict or Section) into ``out_path`` (+ truth and fragment files).

    Returns {"if": ..., "truth": ..., "yaml": ...}.  The three files are written under temporary names
    (``.partial``) and renamed together at the end; on any error or SIGINT/SIGTERM none is left behind.
    """
    sc = load_scenario(scenario, overrides)
    paths = output_paths(out_path)
    reads = files_read(scenario, sc)
    if len(set(map(os.path.abspath, paths.values()))) < len(paths):
        raise UserError(f"output {paths['if']}: the IF, truth and receiver-input names must differ "
                        f"(use a .bin name)")
    if sc.l5.enabled or sc.e5a.enabled:  # + an L5 / E5a file on the same clock (sim/multiband.py)
        from .multiband import simulate_l1_l5
        return simulate_l1_l5(sc, out_path, reads, progress, _Simulator, scale_ionosphere)
    sim = _Simulator(sc)                 # input errors surface here, before any file or directory is made
    scale_ionosphere(sim, sc.atmosphere.iono_scale)
    for kind, p in paths.items():        # missing directories are made (as for every command's outputs)
        check_output(p, reads, what={"if": "output", "truth": "truth file",
                                     "yaml": "receiver-input fragment", "sigmf": "SigMF metadata",
                                     "tag": "PocketSDR tag"}[kind])
    lock = OutputLock(paths["if"]).acquire()
    tmp = {k: v + TMP_SUFFIX for k, v in paths.items()}
    try:
        try:
            sim.run(paths, progress, tmp)
        except OSError as exc:
            raise UserError(write_error_message("output", paths["if"], exc)) from None
        interrupt.check()
        for k in ("truth", "yaml", "sigmf", "tag", "if"):  # the IF file last: its presence means complete
            if k == "tag" and not os.path.exists(tmp[k]):
                remove_files([paths[k]])            # a format PocketSDR does not name: no (stale) tag
                continue
            os.replace(tmp[k], paths[k])
    except BaseException:
        remove_files(tmp.values())
        raise
    finally:
        lock.release()
    return paths


def write_broadcast_nav(scenario, path, overrides=()) -> int:
    """Write the ephemerides and Klobuchar set the scenario's satellites broadcast (every system of the
    scenario: GPS / QZSS LNAV, Galileo I/NAV, BeiDou D1/D2; the satellites the recording holds) as a RINEX 3
    navigation file, mixed when the scenario has several systems: ``navigation.ephemeris`` of an assisted run
    (scripts/tools/scenario_nav.py).  Returns the number of records."""
    from ..gnss.rinex import write_rinex_nav
    sim = _Simulator(load_scenario(scenario, overrides))
    write_rinex_nav(os.fspath(path), list(sim.ephs.values()), sim.iono_b, program="gnssrx simulate")
    return len(sim.ephs)


def scale_ionosphere(sim, factor: float):
    """The true ionosphere of simulator ``sim`` is ``factor`` times its model (atmosphere.iono_scale; the
    broadcast parameters unchanged; exactly no change for 1.0)."""
    if factor != 1.0:
        sim.iono_scale = {p: v * factor for p, v in sim.iono_scale.items()}


# formats written by the numba quantiser in kernel.py; the others go through source.io.Encoder
_FAST_FORMATS = ("int8_iq", "int16_iq", "complex64", "float32_real", "int8_real", "int16_real")


class _Simulator:
    """Models of one scenario and the block loop (see the module docstring for the conventions)."""

    def __init__(self, sc):
        self.sc = sc
        self._time_base(sc)
        self._trajectory(sc)
        self.signals, self.multi, self.gal, bds_src = select_signals(sc)
        cons = self._constellation(sc, bds_src)
        el_scan = self._satellites(sc, cons)
        self._models(sc, el_scan)
        self._signal_plan()
        self.nav = nav_sources(sc, self.prns, self.sat_sig, self.ephs, self.gal_content, self.iono_b, self.week,
                               self.gal, bds_src, self.multi, self.gal_multi)
        self._codes()
        self.amp_k = (2.0 if self.cplx else 4.0) * self.sigma ** 2 / self.fs     # A^2 = amp_k * C/N0
        self.node_step = math.gcd(NODE_STEPS, self.decim)   # geometry nodes (grid steps), on truth rows
        self.truth_prns = None              # the satellites of the truth file (None: all; a band file's own)
        self._tracks = {}

    # ------------------------------------------------------------------------------ set-up steps
    def _time_base(self, sc):
        """Front end (rate, format, noise), the 1-ms grid and its blocks, the reference times of sample 0
        and the noise generator."""
        fe, tm = sc.frontend, sc.time
        self.fs = fe.sample_rate_hz
        self.fmt = fe.format
        self.cplx = is_complex(self.fmt)
        self.if_hz = fe.if_hz
        self.sigma = noise_sigma(sc)
        self.noise = fe.noise
        self.duration = duration = tm.duration_s
        self.n_total = int(round(duration * self.fs))
        if self.n_total < 1:
            raise UserError("time.duration_s is shorter than one sample")
        self.spg = self.fs * GRID_S                               # samples per grid step
        self.n_grid = int(math.ceil(self.n_total / self.spg - 1e-9))
        self.decim = int(round(1000.0 / sc.output.truth_rate_hz))
        blk = max(int(round(sc.output.block_s / GRID_S)), 1)
        self.blk = max(self.decim, blk - blk % self.decim)         # blocks hold whole truth steps

        self.t_ref = t_ref = tm.tow_s                             # receiver clock reading of sample 0
        self.week = tm.gps_week
        self.b0 = sc.clock.bias_s
        self.t0_true = t_ref - self.b0
        self.m_ref = int(math.floor(t_ref * 1000.0 + 1e-6))
        self.r_ref = t_ref - self.m_ref * 1e-3                    # t_ref = m_ref ms + r_ref
        self.m_ref_gal = int(math.floor(t_ref / 4e-3 + 1e-6))     # Galileo: 4-ms code periods
        self.r_ref_gal = t_ref - self.m_ref_gal * 4e-3
        self.rng = np.random.default_rng(np.random.SeedSequence([tm.seed, 1]))

    def _trajectory(self, sc):
        """The receiver trajectory (a CSV one must cover the run)."""
        self.traj = traj = make_trajectory(sc.receiver, lambda p: resolve_path(p, "trajectory CSV"), self.t0_true)
        if isinstance(traj, CsvTrajectory) and (traj.t_first > 1e-6 or traj.t_last < self.duration + 0.01):
            raise UserError(f"trajectory CSV covers {traj.t_first:.3f}..{traj.t_last:.3f} s but the run "
                            f"needs 0..{self.duration:.3f} s after the first sample")

    def _constellation(self, sc, bds_src):
        """Ephemerides, broadcast ionosphere and the atmosphere models; returns the constellation."""
        atm = sc.atmosphere
        cons, self.gal_content = load_ephemerides(sc.constellation, self.week, self.t_ref, self.duration,
                                                  self.gal, bds_src)
        # a recording of several signals with gal_e1: the nominal Galileo constellation beside GPS
        self.gal_multi = multi_gal_content(sc.constellation, self.signals, self.multi, self.week, self.t_ref)
        self.source = cons.source
        self.iono_b = broadcast_iono(atm, cons.iono_utc, self.week, self.t_ref)   # what the messages carry
        self.iono = self.iono_b if atm.ionosphere == "klobuchar" else None       # what delays the signals
        self.tropo = atm.troposphere == "saastamoinen"
        return cons

    def _satellites(self, sc, cons):
        """The chosen satellites that rise above the horizon during the run; returns the elevation scan."""
        con = sc.constellation
        ephs = chosen_ephemerides(con, cons, self.multi, self.week, self.t_ref, self.signals, self.gal_multi)
        self.mask = con.elevation_mask_deg
        el_scan = scan_elevations(ephs, self.traj, self.t0_true, self.duration)
        self.prns = sorted(p for p, e in el_scan[1].items() if np.max(e) >= min(self.mask, 0.0) - 1.0)
        if not self.prns:
            raise UserError("no satellite rises above the horizon during the run")
        self.ephs = {p: ephs[p] for p in self.prns}
        return el_scan

    def _models(self, sc, el_scan):
        """Receiver clock, scintillation, C/N0, front-end impairments and blockage."""
        tm = sc.time
        self.clock = Overlap(ClockGenerator(
            self.b0, sc.clock.freq_error_ppm * 1e-6, *clock_h(sc), GRID_S, self.duration,
            np.random.default_rng(np.random.SeedSequence([tm.seed, 2])),
            aging_per_s=sc.clock.aging_ppb_per_s * 1e-9, white_fm_corner_hz=sc.clock.white_fm_corner_hz).take)
        self.scint = scintillation_streams(sc.scintillation, self.prns, tm.seed, GRID_S)
        self.cn0 = Cn0Model(sc.cn0)
        self.impair = Impairments(sc.impairments, self.fs, self.if_hz, self.sigma, self.cplx)
        self.blockage = Blockage(sc.blockage, self.prns, self.duration, tm.seed, el_scan, self.mask)

    def _signal_plan(self):
        """Per satellite (key): its signal, the signal's PRN and IF (several signals: one LO, the first
        signal at frontend.if_hz), and the scale of its ionospheric delay."""
        first = self.signals[0]
        self.signal = first
        self.sat_sig = {}
        for p in self.prns:
            letter, q = split_key(p) if self.multi else (first.system, p)
            sig = next(g for g in self.signals if g.system == (letter if letter in "CE" else "G")) if self.multi \
                else first
            self.sat_sig[p] = (sig, q, self.if_hz + (sig.carrier_hz - first.carrier_hz))
        for sig in self.signals[1:]:
            f_if = self.if_hz + (sig.carrier_hz - first.carrier_hz)
            if not (abs(f_if) < self.fs / 2 and (self.cplx or f_if > 0)):
                raise UserError(f"signal {sig.name} would sit at IF {f_if / 1e6:+.3f} MHz (frontend.if_hz + its "
                                f"carrier - {first.name}'s), outside the {self.fs / 1e6:g} MS/s band")
        # several signals: the one Klobuchar model (the GPS set, L1 delays) is the ionosphere of all; a signal
        # on another carrier is delayed (f_L1 / f)^2 times as much (B1I: +1.84 %).  One signal: the model's
        # delay as it is (a BeiDou set gives B1I delays, BDS-SIS-ICD-B1I)
        self.iono_scale = {p: (first.carrier_hz / self.sat_sig[p][0].carrier_hz) ** 2 if self.multi else 1.0
                           for p in self.prns}

    def _codes(self):
        """The spreading code of each satellite (Galileo: the E1-B and E1-C BOC(1,1) rows)."""
        self.codes = {p: self.sat_sig[p][0].code(self.sat_sig[p][1]) for p in self.prns}
        gal = [p for p in self.prns if self.sat_sig[p][0].system == "E"]
        if gal:                                 # E1-B and E1-C rows: BOC(1,1) half-chips, each half the power
            from ..gnss.gal_codes import boc11, e1b_code, e1c_code
            k = np.float32(1.0 / math.sqrt(2.0))
            self.gal_codes = {p: (k * boc11(e1b_code(self.sat_sig[p][1])), -k * boc11(e1c_code(self.sat_sig[p][1])))
                              for p in gal}

    def attrs(self) -> dict:
        """The truth file's attributes (scenario, time base, format, conventions)."""
        sc = self.sc
        return {
            "scenario": sc.to_yaml(), "gnssrx_version": __version__, "seed": sc.time.seed,
            "gps_week": self.week, "start_gps_tow_s": self.t_ref, "sample_rate_hz": self.fs,
            "if_hz": self.if_hz, "format": self.fmt, "duration_s": self.duration, "n_samples": self.n_total,
            "noise_sigma": self.sigma, "ephemeris_source": self.source,
            "signals": ",".join(g.name for g in self.signals), "system": MIXED if self.multi else self.signal.system,
            "truth_rate_hz": 1000.0 / self.decim,
            "conventions": (
                "time_s = sample_index / sample_rate_hz; receiver clock reading = start_gps_tow_s + time_s; "
                "clock_bias_m = c (clock reading - gps_tow); gps_tow = true GPS time (s since the start of "
                "gps_week); pseudorange_m = c (clock reading - satellite transmit time); doppler_hz = "
                "d(carrier_phase_cycles)/d(time_s), > 0 approaching, includes the oscillator error; "
                "signal = A code data exp(+j 2 pi (if_hz time_s + carrier_phase_cycles))"),
        }

    # ------------------------------------------------------------------------------ the block loop
    def run(self, paths, progress, tmp=None):
        """Write the files under the names ``tmp`` (default: ``paths``); the receiver input fragment
        names the final ones."""
        tmp = tmp or paths
        sat_attrs = {p: {"toe": e.toe, "iode": e.iode, "week": e.week} for p, e in self.ephs.items()}
        self.writer = None
        self.fh = open(tmp["if"], "wb")
        self.writer = TruthWriter(tmp["truth"], self.attrs(), self.truth_prns or self.prns, sat_attrs,
                                  system=MIXED if self.multi else self.signal.system)
        fe = self.sc.frontend
        self.encoder = None if self.fmt in _FAST_FORMATS else Encoder(self.fmt, 1.0, fe.bit_order, fe.encoding)
        bar = None
        try:
            self.blockage.write(self.writer.f)
            if progress:
                from tqdm import tqdm
                bar = tqdm(total=round(self.duration, 3), unit="s", desc="simulate", leave=False,
                           bar_format="{l_bar}{bar}| {n:.1f}/{total:.1f} s [{elapsed}<{remaining}]")
            g0 = 0
            while g0 < self.n_grid:
                interrupt.check()                   # SIGINT/SIGTERM: stop between blocks
                n = min(self.blk, self.n_grid - g0)
                self._block(g0, n)
                if bar is not None:
                    bar.update(round(n * GRID_S, 3))
                g0 += n
            if self.encoder is not None:
                self.fh.write(self.encoder.flush())
        finally:
            self.fh.close()
            if self.writer is not None:
                self.writer.close()
            if bar is not None:
                bar.close()
        write_companions(paths, tmp, fe, self.signal, self.signals, self.multi, self.fs, self.if_hz, self.week,
                         self.t_ref)

    def _visibility(self, t_rel, el_deg):
        return self.blockage.visibility(t_rel, el_deg, self.mask)

    def _track(self, prn, t_lo, t_hi):
        tr = self._tracks.get(prn)
        if tr is None or not tr.covers(t_lo, t_hi):
            tr = self._tracks[prn] = SatelliteTrack(self.ephs[prn], t_lo, max(t_hi, t_lo + 30.0))
        return tr

    def _block(self, g0, n):
        """Grid steps g0 .. g0+n-1 (grid points g0 .. g0+n): append the samples and the truth rows.

        The propagation geometry is computed at nodes every ``node_step`` grid points (and the last
        point); the smooth parts of the code and carrier delays are carried to every grid point by cubic
        Hermite interpolation (values and exact rates at the nodes), the receiver clock, scintillation and
        visibility are evaluated at every grid point.
        """
        b = self._block_times(g0, n)
        self._block_geometry(b)
        self._block_segments(b, g0)
        sig, truth_sat = [], {}
        for i, p in enumerate(self.prns):
            s = self._sat_delays(b, i, p)
            self._sat_rows(b, p, s, sig)
            if b.rows.size:
                truth_sat[p] = self._sat_truth(b, i, p, s)
        if b.n_samp > 0:
            self._write_samples(b, sig)
        if b.rows.size:
            gr = b.nodes[b.rows]
            c = C_LIGHT
            self.writer.append({"time_s": b.t_rel[gr], "gps_tow": b.t_abs[gr], "ecef": b.rx_pos[b.rows],
                                "velocity_ecef": b.rx_vel[b.rows], "accel_ecef": b.rx_acc[b.rows],
                                "clock_bias_m": c * b.bias[gr], "clock_drift_mps": c * b.y[gr]}, truth_sat)

    # ------------------------------------------------------------------------------ block steps
    def _block_times(self, g0, n):
        """The block's grid (receiver, true and absolute times, clock bias and drift) and its geometry
        nodes, as a namespace the other block steps fill in."""
        g = g0 + np.arange(n + 1)
        t_rel = g * GRID_S                                   # receiver time since sample 0
        bias, y = self.clock.get(n)                          # clock bias (s), drift (s/s)
        t_true_rel = t_rel - (bias - self.b0)                # true time since the first sample
        t_abs = self.t_ref + t_rel - bias                    # true GPS time (s of the scenario week)
        nodes = np.unique(np.append(np.arange(0, n + 1, self.node_step), n))
        b = SimpleNamespace(n=n, g=g, t_rel=t_rel, bias=bias, y=y, t_abs=t_abs, nodes=nodes,
                            tn_rel=t_rel[nodes], tn_true=t_true_rel[nodes], tn_abs=t_abs[nodes], yn=y[nodes])
        b.interp = nodes.size < n + 1                        # nodes sparser than the grid: interpolate
        if nodes.size > 1:
            dtn = np.gradient(b.tn_true)

            def rate(v):                                    # d/dt (true time) at the nodes
                return np.gradient(v) / dtn
        else:
            def rate(v):
                return np.zeros_like(v)
        b.rate = rate
        b.rows = np.nonzero((g[nodes] % self.decim == 0) & (nodes < n) & (b.tn_rel < self.duration - 1e-12))[0]
        return b

    def _block_geometry(self, b):
        """Receiver state and each satellite's propagation geometry at the nodes; elevations and
        visibility on the grid."""
        b.rx_pos, b.rx_vel, b.rx_acc = self.traj.state(b.tn_true)
        lat, lon, hgt = ecef2lla(b.rx_pos)
        b.geo = {}
        for p in self.prns:
            track = self._track(p, b.tn_abs[0] - 0.2, b.tn_abs[-1])
            b.geo[p] = satellite_geometry(track, b.tn_abs, b.rx_pos, b.rx_vel, lat, lon, hgt, self.iono,
                                          self.tropo, self.iono_scale[p])
        b.el_n = np.array([np.degrees(b.geo[p]["el"]) for p in self.prns])
        b.el_deg = np.array([np.interp(b.t_rel, b.tn_rel, e) for e in b.el_n]) if b.interp else b.el_n
        b.visible = self._visibility(b.t_rel, b.el_deg)

    def _block_segments(self, b, g0):
        """The block's samples: grid step j covers samples seg_start[j] .. seg_start[j+1]-1."""
        b.first = int(math.ceil(g0 * self.spg - 1e-9))
        seg_pos = b.g * self.spg
        seg_abs = np.minimum(np.ceil(seg_pos - 1e-9).astype(np.int64), self.n_total)
        b.seg_x0 = seg_abs[:-1] - seg_pos[:-1]
        b.seg_start = seg_abs - b.first
        b.n_samp = int(b.seg_start[-1])

    def _sat_delays(self, b, i, p):
        """Code and carrier delays of satellite p on the grid (with the receiver clock), its code phase,
        carrier phase, C/N0, amplitude and scintillation: a namespace for the rows and the truth."""
        c = C_LIGHT
        n, q, yn, t_rel = b.n, b.geo[p], b.yn, b.t_rel
        i_dot, t_dot = b.rate(q["iono_m"]), b.rate(q["tropo_m"])
        tau_dot = (q["rho_dot"] + i_dot + t_dot) / c
        clk_rate = q["clk_dot"] * (1.0 - tau_dot)       # d dt_sv(t - tau) / dt
        # delays without the receiver clock, and their rates w.r.t. receiver time (dt/dT = 1/(1+y))
        gc = (q["rho"] + q["iono_m"] + q["tropo_m"]) / c - q["clk"]
        gp = (q["rho"] - q["iono_m"] + q["tropo_m"]) / c - q["clk"]
        gc_dot = (tau_dot - clk_rate) / (1.0 + yn)
        gp_dot = ((q["rho_dot"] - i_dot + t_dot) / c - clk_rate) / (1.0 + yn)
        if b.interp:
            d_code = b.bias + hermite(b.tn_rel, gc, gc_dot, t_rel)
            d_carr = b.bias + hermite(b.tn_rel, gp, gp_dot, t_rel)
        else:
            d_code, d_carr = b.bias + gc, b.bias + gp
        sig_p, _, if_p = self.sat_sig[p]
        chips_total = (self.r_ref + t_rel - d_code) * sig_p.chip_rate  # since ms m_ref, sat. time
        if p in self.scint:
            s_amp, s_ph = self.scint[p].get(n)
        else:
            s_amp, s_ph = np.ones(n + 1), np.zeros(n + 1)
        cn0_db = self.cn0(p, t_rel, b.el_deg[i])
        amp = np.sqrt(self.amp_k * 10.0 ** (cn0_db / 10.0)) * s_amp * b.visible[i]
        carr = -sig_p.carrier_hz * d_carr + s_ph / (2.0 * np.pi)
        if sig_p.system == "E":                          # Galileo: chips since a 4-ms period boundary
            chips_total = (self.r_ref_gal + t_rel - d_code) * sig_p.chip_rate
        return SimpleNamespace(sig=sig_p, if_hz=if_p, f_carr=sig_p.carrier_hz, code_n=float(sig_p.code_len),
                               d_code=d_code, gp_dot=gp_dot, chips_total=chips_total, carr=carr, amp=amp,
                               cn0_db=cn0_db, s_amp=s_amp, s_ph=s_ph)

    def _sat_rows(self, b, p, s, sig):
        """Append satellite p's kernel rows (p, chips, phase, amplitude, data signs, code) to sig (two rows
        for Galileo: E1-B and E1-C); none when the block has no samples or the satellite no signal."""
        if not (b.n_samp > 0 and np.any(s.amp > 0)):
            return
        code_n, chips_total, t_rel = s.code_n, s.chips_total, b.t_rel
        if s.sig.system == "E":
            per0 = int(math.floor(chips_total[0] / code_n))
            chips_blk = 2.0 * (chips_total - per0 * code_n)          # BOC(1,1) half-chips
            count = int(chips_blk[-1] // (2 * code_n)) + 2
            sym_b, sec_c = self.nav[p].signs(self.m_ref_gal + per0, count)
            ph = s.if_hz * t_rel + s.carr
            a32 = s.amp.astype(np.float32)
            sig.append((p, chips_blk, ph, a32, sym_b, self.gal_codes[p][0]))
            sig.append((p, chips_blk, ph, a32, sec_c, self.gal_codes[p][1]))
            return
        ms0 = int(math.floor(chips_total[0] / code_n))
        chips_blk = chips_total - ms0 * code_n
        if s.sig.name == "bds_b1i" and not self.multi and \
                self.sc.constellation.source not in ("bds_nominal", "bds_rinex"):
            dsign = data_signs(p, self.m_ref + ms0, int(chips_blk[-1] // code_n) + 2,
                               self.sc.time.seed, self.sc.navigation.data)
        else:
            dsign = self.nav[p].signs(self.m_ref + ms0, int(chips_blk[-1] // code_n) + 2)
        sig.append((p, chips_blk, s.if_hz * t_rel + s.carr, s.amp.astype(np.float32), dsign, self.codes[p]))

    def _sat_truth(self, b, i, p, s):
        """Satellite p's truth rows of the block."""
        q, r = b.geo[p], b.rows
        gr = b.nodes[r]                                # grid indices of the truth rows
        y = b.y
        ph_rate = np.gradient(s.s_ph, GRID_S)[gr] if b.n >= 1 else np.zeros(r.size)
        doppler = -s.f_carr * (y[gr] / (1.0 + y[gr]) + s.gp_dot[r]) + ph_rate / (2.0 * np.pi)
        return {
            "time_s": b.t_rel[gr], "gps_tow": b.t_abs[gr], "pseudorange_m": C_LIGHT * s.d_code[gr],
            "range_m": q["rho"][r], "range_rate_mps": q["rho_dot"][r], "doppler_hz": doppler,
            "carrier_phase_cycles": s.carr[gr], "code_phase_chips": np.mod(s.chips_total[gr], s.code_n),
            "cn0_dbhz": s.cn0_db[gr], "visible": b.visible[i][gr], "scint_amplitude": s.s_amp[gr],
            "scint_phase_rad": s.s_ph[gr], "elevation_deg": b.el_n[i][r],
            "azimuth_deg": np.degrees(q["az"][r]), "iono_delay_m": q["iono_m"][r],
            "tropo_delay_m": q["tropo_m"][r], "sat_clock_s": q["clk"][r]}

    def _write_samples(self, b, sig):
        """Synthesise the block's samples from the kernel rows (one call per code length), add noise and
        the front-end impairments, quantise and write them."""
        n_samp = b.n_samp
        out = np.zeros(n_samp, np.complex64)
        for code_len in sorted({r[5].size for r in sig}):               # (one call per code length)
            grp = [r for r in sig if r[5].size == code_len]
            n_ms = max(r[4].size for r in grp)
            dsign = np.ones((len(grp), n_ms), np.float32)
            for k, r in enumerate(grp):
                dsign[k, :r[4].size] = r[4]
            phase = np.stack([r[2] for r in grp])
            synth_block(out, b.seg_start, b.seg_x0, 1.0 / self.spg,
                        np.stack([r[5] for r in grp]), np.stack([r[1] for r in grp]),
                        np.mod(phase, 1.0), np.diff(phase, axis=1), np.stack([r[3] for r in grp]), dsign)
        if self.noise:
            view = out.view(np.float32)
            if self.cplx:
                view += np.float32(self.sigma) * self.rng.standard_normal(view.size, dtype=np.float32)
            else:
                view[0::2] += np.float32(self.sigma) * self.rng.standard_normal(n_samp, dtype=np.float32)
        out = self.impair.apply(out, b.first)          # front-end impairments (sim/impairments.py)
        if self.encoder is None:
            quantize_fast(out, self.fmt).tofile(self.fh)
        else:
            self.fh.write(self.encoder.encode(out))
