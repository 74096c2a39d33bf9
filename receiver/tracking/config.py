"""The ``tracking`` section of the receiver config (schema fragment of the tracking stage).

The carrier-loop choices are the carrier registry (:data:`receiver.tracking.carrier.REGISTRY`), the C/N0
estimators the channel's (:data:`receiver.tracking.scalar.CN0_ESTIMATORS`); receiver/schema.py assembles
this fragment into the receiver's schema.
"""
from __future__ import annotations

from ..config import P
from .carrier import REGISTRY
from .scalar import CN0_ESTIMATORS

CARRIER_VARIANTS = tuple(REGISTRY)

SCHEMA = {
    "max_channels": P(12, "int", "maximum number of tracking channels", lo=1, hi=64),
    "integration_ms": P(1, "int", "coherent integration after bit sync (1, 2, 4, 5, 10, 20 ms)",
                        choices=(1, 2, 4, 5, 10, 20)),
    "pull_in_ms": P(300, "int", "duration of FLL-assisted pull-in (ms)", lo=0),
    "fll_bw_hz": P(1.0, "float", "FLL noise bandwidth during pull-in (1st-order FLL aiding a 2nd-order "
                                  "PLL; wider FLLs random-walk at low C/N0)", lo=0.0),
    "pll_bw_hz": P(25.0, "float", "PLL noise bandwidth", lo=0.1),
    "pll_order": P(3, "int", "PLL order", choices=(2, 3)),
    "dll_bw_hz": P(2.0, "float", "DLL noise bandwidth (carrier aided)", lo=0.01),
    "dll_order": P(2, "int", "DLL order (2 absorbs a code/carrier rate mismatch)", choices=(1, 2)),
    "dll_bw_pull_in_hz": P(4.0, "float", "DLL noise bandwidth during pull-in", lo=0.01),
    "early_late_chips": P(0.5, "float", "early-late spacing (total, chips)", lo=0.05, hi=1.5),
    "early_late_snap": P(False, "bool", "round the early/late offsets to whole samples on every channel "
                                        "(0.5 chip becomes 0.79 chip at 2.6 MS/s: 1.8x the 3D RMS on the "
                                        "third-party recording); off: whole samples only while a channel "
                                        "pulls in and on weak channels, the exact spacing otherwise "
                                        "(docs: Tracking)"),
    "cn0_window_ms": P(200, "int", "window for the C/N0 estimator (ms)", lo=20),
    "cn0_estimator": P("snv", "str", "C/N0 estimator: snv (signal-to-noise variance of the locked "
                                     "prompt; M2M4 before lock) or m2m4", choices=tuple(CN0_ESTIMATORS)),
    "lock_cn0_min_dbhz": P(25.0, "float", "C/N0 below which lock is declared lost", lo=0.0),
    "lock_ratio_min": P(1.5, "float", "PLL lock detector: lock while low-passed |I| exceeds this "
                                      "times low-passed |Q|", lo=1.0),
    "lost_ms": P(200, "int", "time below the lock thresholds before a channel declares the signal lost "
                            "(its satellite is then re-acquired around the prediction; docs: Tracking, signal outages)",
                 lo=10),
    "lost_grace_ms": P(1000, "int", "a channel is declared lost only after this long below the lock "
                                    "thresholds while it is younger than this (since its pull-in began): a "
                                    "weak signal needs time to reach phase lock", lo=0),
    "presence": {
        "window_ms": P(20, "int", "signal-presence test: the prompt power over windows of this length is "
                                  "compared with its level while the signal was present; a vanished "
                                  "signal is seen within 1-2 windows (the lock detectors and the C/N0 "
                                  "window lag it by 0.15-0.4 s); 0 = off", lo=0),
        "drop_db": P(10.0, "float", "the signal is absent when the window power falls this far below its "
                                    "level while present", lo=1.0),
        "min_cn0_dbhz": P(30.0, "float", "only a channel with at least this C/N0 can be declared absent by "
                                         "the test (weaker signals: the lock detectors alone; a fade of a "
                                         "weak signal must not read as a loss)", lo=0.0),
        "lost_ms": P(40, "int", "absent this long: the channel declares the signal lost (then re-acquired "
                                "around the prediction); meanwhile it has no lock and C/N0 0, so no "
                                "measurement of it enters a fix (scalar or vector)", lo=1),
    },
    "reacquire_s": P(5.0, "float", "interval between cold re-acquisition attempts for PRNs never tracked "
                                   "or no longer predictable", lo=0.1),
    "weak": {
        "enabled": P(True, "bool", "weak-signal tracking: a channel whose C/N0 estimates stay below "
                                   "cn0_dbhz during the first second after its pull-in is weak (until it "
                                   "is lost or handed over, exit_cn0_dbhz); a channel that starts strong "
                                   "keeps the normal loops and thresholds above until it fades (fade)"),
        "fade": P(True, "bool", "fade hand-down: a strong channel with bit sync that the normal lock "
                                "detectors or the presence test would declare lost goes on with the weak "
                                "loops instead; it has no lock until their first C/N0 window (~0.25 s) "
                                "says the signal is there (a 10-20 dB fade), else it is lost then "
                                "(built-in scalar loops only; docs: Tracking, weak signals)"),
        "cn0_dbhz": P(32.0, "float", "C/N0 below which a starting channel is weak (the acquisition's "
                                     "estimate opens a channel weak at once)", lo=0.0, hi=60.0),
        "integration_ms": P(20, "int", "coherent integration of a weak channel after bit sync",
                            choices=(1, 2, 4, 5, 10, 20)),
        "pll_bw_hz": P(10.0, "float", "PLL noise bandwidth of a weak channel (built-in loop; B T <= 0.2 "
                                      "at 20 ms)", lo=0.1),
        "dll_bw_hz": P(0.5, "float", "DLL noise bandwidth of a weak channel (carrier aided: the code noise, "
                                     "not the dynamics, sets it)", lo=0.01),
        "fll_bw_hz": P(0.0, "float", "FLL noise bandwidth of a weak channel's pull-in (the 1-ms frequency "
                                     "discriminator is noise below ~30 dB-Hz; 0: the PLL alone, started "
                                     "from the acquisition's fine Doppler)", lo=0.0),
        "repull_fll_bw_hz": P(3.0, "float", "re-pull: FLL noise bandwidth that steers a channel that "
                                            "started weak, has bit sync and has been out of lock for "
                                            "lock_window_ms, from the rotation between the two halves of "
                                            "each 20-ms epoch (0: off, the PLL alone)", lo=0.0, hi=10.0),
        "lost_grace_ms": P(3000, "int", "lost-grace time of a young weak channel (tracking.lost_grace_ms "
                                        "for the others)", lo=0),
        "lock_ratio_min": P(1.25, "float", "lock ratio of a weak channel (low-passed |I| / |Q|)", lo=1.0),
        "lock_window_ms": P(200.0, "float", "low-pass time constant of a weak channel's lock detector (ms)",
                            lo=1.0),
        "lock_cn0_min_dbhz": P(20.0, "float", "C/N0 below which a weak channel's lock is lost", lo=0.0),
        "bit_sync_ms": P(1000, "int", "bit sync by the energy of 20-ms prompt sums per edge hypothesis "
                                      "after this many ms when the sign-change histogram has not decided "
                                      "(0: off)", lo=0),
        "dll_hold_ms": P(2000, "int", "a weak channel's DLL keeps tracking.dll_bw_pull_in_hz this long "
                                      "after its pull-in (the pull-in's code error converges at the "
                                      "normal rate; its rate integrator at dll_bw_hz throughout), then "
                                      "narrows to dll_bw_hz; the navigation uses its measurements "
                                      "navigation.settle_s after that", lo=0),
        "narrow_el_after_hold": P(True, "bool", "a weak channel's early-late spacing is tracking.early_late_chips "
                                                "once its DLL hold (dll_hold_ms) is over, instead of the "
                                                "whole-sample spacing of the pull-in for as long as it is weak: "
                                                "the settled code noise goes as the spacing (at 2.6 MS/s 0.5 "
                                                "against 0.79 chip)"),
        "exit_cn0_dbhz": P(35.0, "float", "a weak channel whose C/N0 estimates reach this in 3 windows in a "
                                          "row (tracking.cn0_window_ms each) while locked is handed over to "
                                          "the normal loops (the acquisition's estimate reads up to ~3 dB "
                                          "low; 0: weak until lost)", lo=0.0, hi=60.0),
    },
    "reacquisition": {
        "doppler_hz": P(40.0, "float", "Doppler half-window of the hot search right after a loss (error of "
                                       "the Doppler extrapolated from the last tracked state)", lo=0.0),
        "code_chips": P(1.5, "float", "code-phase half-window of the hot search right after a loss",
                        lo=0.0),
        "accel_mps2": P(5.0, "float", "receiver acceleration bound along the line of sight: the windows "
                                      "widen by accel t / lambda (Doppler) and accel t^2 / 2 (code) with "
                                      "the outage length t (warm start)", lo=0.0),
        "speed_mps": P(60.0, "float", "receiver speed bound: caps the widening at 2 speed / lambda "
                                      "(Doppler) and 2 speed t (code)", lo=0.0),
        "max_age_s": P(300.0, "float", "outages longer than this fall back to the cold full-grid search",
                       lo=0.0),
        "coherent_ms": P(2, "int", "coherent integration of the narrow search (ms)", lo=1, hi=10),
        "noncoherent": P(10, "int", "non-coherent sums of the narrow search", lo=1, hi=100),
        "pfa": P(1e-4, "float", "false-alarm probability over the narrow search window", lo=1e-12,
                 hi=0.5),
        "pull_in_ms": P(40, "int", "FLL-assisted pull-in of a re-acquired channel (ms)", lo=0),
        "dll_bw_pull_in_hz": P(15.0, "float", "DLL noise bandwidth during a re-acquired channel's pull-in "
                                             "(1st order: the code error left by the narrow search decays "
                                             "with time constant 1 / (4 B))", lo=0.01),
        "settle_s": P(0.1, "float", "a re-acquired channel's measurements are used this long after its "
                                    "pull-in", lo=0.0),
        "settle_predicted_s": P(0.02, "float", "the same for a hot re-acquisition whose code phase was "
                                               "predicted to better than 0.05 chip and found by the search "
                                               "within 0.5 chip of the prediction (the channel starts on the "
                                               "prediction: no DLL transient to wait for)", lo=0.0),
        "search_step_s": P(0.125, "float", "narrow searches run at this step through each chunk just tracked "
                                           "(a returning satellite is found within a step, not a chunk); "
                                           "0: once per chunk, at its end", lo=0.0),
        "search_after_s": P(0.15, "float", "narrow searches start this long after the last good epoch "
                                           "of a lost satellite", lo=0.0),
    },
    "carrier": {
        "variant": P("pll", "str", "carrier loop variant: pll (built-in FLL-assisted PLL), cpll_atan "
                                   "(ATAN Costas PLL, loop filter of order `order`), ekf (I/Q extended "
                                   "Kalman filter), pli_ekf (EKF with PLI-weighted observation), kf "
                                   "(Kalman-filter PLL on the ATAN discriminator), adaptive_kf (kf with "
                                   "innovation-scaled Q and NWPR-C/N0 R); auto: chosen per channel when it "
                                   "opens, by the acquisition's C/N0 estimate (auto_weak below "
                                   "tracking.weak.cn0_dbhz, auto_strong otherwise)",
                     choices=CARRIER_VARIANTS + ("auto",)),
        "auto_weak": P("adaptive_kf", "str", "variant auto: the loop of a channel the acquisition estimates "
                                             "below tracking.weak.cn0_dbhz", choices=CARRIER_VARIANTS),
        "auto_strong": P("pll", "str", "variant auto: the loop of the other channels",
                         choices=CARRIER_VARIANTS),
        "t_coh_ms": P(None, "int", "coherent integration of the carrier loop after bit sync (empty: "
                                   "tracking.integration_ms); limited to the data-symbol length unless "
                                   "dataless", nullable=True, choices=(1, 2, 4, 5, 10, 20)),
        "dataless": P(False, "bool", "the signal carries no data symbols (simulator navigation.data: "
                                     "false): integrate across symbol edges; overlay codes still apply"),
        "bn_hz": P(15.0, "float", "cpll_atan: loop noise bandwidth", lo=0.1),
        "order": P(3, "int", "cpll_atan: loop order", choices=(2, 3)),
        "clock_h0": P(2e-19, "float", "kf/ekf process noise: oscillator white FM level h0", lo=0.0),
        "clock_h_2": P(2e-20, "float", "kf/ekf process noise: oscillator random-walk FM level h_-2",
                       lo=0.0),
        "kf": {
            "cn0_dbhz": P(35.0, "float", "kf: design C/N0 for the discriminator variance R", lo=0.0),
            "jerk_psd": P(4.0, "float", "kf: PSD of the white line-of-sight jerk ((m/s^3)^2/Hz)",
                          lo=0.0),
            "window": P(20, "int", "adaptive_kf: innovation window m (epochs)", lo=2),
            "cn0_tau_s": P(0.5, "float", "adaptive_kf: NWPR C/N0 smoothing time constant", lo=0.0),
        },
        "ekf": {
            "bn_hz": P(15.0, "float", "ekf/pli_ekf: loop bandwidth at the design C/N0 (sets the "
                                      "white-snap process noise)", lo=0.1),
            "cn0_dbhz": P(40.0, "float", "ekf/pli_ekf: design C/N0 for bn_hz", lo=0.0),
            "amp_tau_s": P(0.05, "float", "ekf/pli_ekf: smoothing of the amplitude / noise power "
                                          "estimates", lo=0.0),
            "cn0_tau_s": P(0.5, "float", "ekf/pli_ekf: NWPR C/N0 smoothing time constant", lo=0.0),
            "pli_tau_s": P(0.1, "float", "pli_ekf: low-pass time constant of I^2, Q^2 in the PLI "
                                         "(0: the epoch's own I, Q)", lo=0.0),
            "pli_min": P(0.0, "float", "pli_ekf: the PLI weight is clipped to [pli_min, 1] (0: ours, a "
                                       "weight; -1: the paper's unclipped PLI = cos 2 phi)", lo=-1.0, hi=1.0),
        },
    },
}
