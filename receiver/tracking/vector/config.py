"""The ``vector`` section of the receiver config (schema fragment of the vector loops) and its check.

The variant choices are the vector registry (:data:`receiver.tracking.vector.REGISTRY`), the oscillator
classes the clock table (:data:`receiver.gnss.clock.OSCILLATORS`); receiver/schema.py assembles this
fragment into the receiver's schema.
"""
from __future__ import annotations

from ...config import P, Section
from ...errors import UserError
from ...gnss.clock import OSCILLATORS
from . import REGISTRY

#: the signals the vector loops track (any mix of them, one clock bias per system)
VECTOR_SIGNALS = ("gps_l1ca", "bds_b1i", "gal_e1")

SCHEMA = {
    "enabled": P(False, "bool", "hand scalar channels over to a vector loop (gps_l1ca incl. QZSS, "
                                "bds_b1i, gal_e1 (4-ms E1-C pilot epochs), or any mix: one inter-system "
                                "bias per extra system)"),
    "variant": P("adaptive_r", "str", "vector loop variant",
                 choices=tuple(REGISTRY)),
    "start_s": P(None, "float", "handover time in seconds from the first sample (empty: 5 s after "
                                "the first valid fix)", nullable=True, lo=0.0),
    "integration_ms": P(1, "int", "vector-loop epoch T = coherent integration (ms; > 1 only on "
                                  "bit-synchronised channels, the others average 1 ms epochs; at most "
                                  "10 ms: an epoch must fit in the pipeline's 30 ms chunk overlap)",
                        choices=(1, 2, 4, 5, 10)),
    "r_code_m2": P(1500.0, "float", "code discriminator variance R (m^2; fixed_r, cv, initial value of "
                                    "the adaptive variants)", lo=1e-6),
    "r_carrier_m2s2": P(900.0, "float", "frequency discriminator variance R ((m/s)^2)", lo=1e-6),
    "r_model": P("fixed", "str", "measurement noise R of the discriminators: fixed = r_code_m2 / "
                                 "r_carrier_m2s2 for every channel (the papers'); cn0 = per channel from its "
                                 "C/N0 estimate and integration time (vector.r_cn0; the adaptive variants "
                                 "start from it)", choices=("fixed", "cn0")),
    "r_cn0": {
        "min_cn0_dbhz": P(22.0, "float", "r_model cn0: C/N0 used for R never below this (an estimate on "
                                         "noise alone reads 20-30 dB-Hz)", lo=0.0),
        "floor_code_m2": P(4.0, "float", "r_model cn0: lower limit of the code R (m^2)", lo=1e-9),
        "floor_carrier_m2s2": P(0.05, "float", "r_model cn0: lower limit of the frequency R ((m/s)^2)",
                                lo=1e-9),
        "scale": P(1.0, "float", "r_model cn0: factor on both theoretical variances", lo=1e-6),
    },
    "motion_model": P("cv", "str", "fixed_r/adaptive_r kinematic model: cv = constant velocity (the "
                                   "papers' 8 states), ca = constant acceleration (3 more states)",
                      choices=("cv", "ca")),
    "q_accel": P(10.0, "float", "fixed_r/adaptive_r, motion_model cv: PSD of the white receiver "
                                "acceleration per axis (m^2/s^3)", lo=0.0),
    "q_jerk": P(1.0, "float", "fixed_r/adaptive_r, motion_model ca: PSD of the white receiver jerk per "
                              "axis (m^2/s^5)", lo=0.0),
    "q_vertical_scale": P(1.0, "float", "fixed_r/adaptive_r: factor on the kinematic PSD along the local "
                                        "vertical (at handover); 1 = isotropic, a land vehicle ~0.001",
                          lo=0.0),
    "init_sigma_acc_mps2": P(2.0, "float", "motion_model ca: initial acceleration standard deviation "
                                           "(m/s^2; the acceleration starts at zero)", lo=0.0),
    "clock_class": P("tcxo", "str", "oscillator class of the clock process noise (h0, h_-2)",
                     choices=tuple(OSCILLATORS)),
    "code_carrier_drift": P(True, "bool", "estimate a code-minus-carrier clock drift state (front ends "
                                          "whose oscillator error reaches the carrier only; ionospheric "
                                          "divergence)"),
    "q_code_carrier_drift": P(1e-4, "float", "PSD of the code-minus-carrier drift random walk "
                                             "((m/s)^2/s)", lo=0.0),
    "init_sigma_pos_m": P(10.0, "float", "initial position standard deviation at handover", lo=0.0),
    "init_sigma_vel_mps": P(1.0, "float", "initial velocity standard deviation at handover", lo=0.0),
    "cn0_mask_dbhz": P(None, "float", "channels below this C/N0 are predicted only (no measurement "
                                      "update); empty: every channel updates (the papers' setting)",
                       nullable=True),
    "innovation_gate_sigma": P(0.0, "float", "skip a channel's code / carrier update when its innovation "
                                             "exceeds this many standard deviations (0 = off, the papers' "
                                             "setting); the innovation still feeds the adaptive R",
                               lo=0.0),
    "cn0_window_ms": P(200, "int", "C/N0 (M2M4) window of the vector channels: it decides vector lock and "
                                   "coasting, so it sets how fast a lost signal is noticed", lo=20),
    "lock_cn0_dbhz": P(32.0, "float", "vector lock: C/N0 (M2M4, vector.cn0_window_ms) above which a "
                                      "vector channel counts as tracked (records' pll_lock, fixes' "
                                      "n_sats and DOPs; M2M4 on noise alone reads 20-30 dB-Hz)"),
    "weak_lock_cn0_dbhz": P(24.0, "float", "vector lock of weak GPS / QZSS L1 C/A channels: a channel below "
                                           "lock_cn0_dbhz counts as tracked while the C/N0 of its bit-aligned "
                                           "20-ms prompt sums (M2M4 over vector.weak_lock_window_ms) is at least "
                                           "this and the signal-presence test finds it present (0 = off; over "
                                           "1 s noise alone reads below ~23 dB-Hz)", lo=0.0),
    "weak_lock_window_ms": P(1000, "int", "window of the weak-channel lock detector (ms, whole data bits)",
                             lo=100),
    "coast_mask": P(True, "bool", "while fewer than 4 channels carry signal (C/N0 above lock_cn0_dbhz) the "
                                  "channels without signal are predicted only (no measurement update): "
                                  "the filter coasts on its motion model instead of on noise"),
    "reinit_sigma_m": P(30.0, "float", "an outage the filter cannot bridge: when its 3D position standard "
                                       "deviation passes this while coasting, the channels fall back to "
                                       "scalar tracking and the handover starts again from the next scalar "
                                       "fix (0 = never)", lo=0.0),
    "drop_elevation_deg": P(-2.0, "float", "vector channels whose satellite sets below this elevation are "
                                           "dropped", lo=-90.0, hi=90.0),
    "add_predicted": P(True, "bool", "open channels predicted from the navigation solution for "
                                     "satellites with an ephemeris above navigation.elevation_mask_deg "
                                     "(no acquisition needed)"),
    "adaptive_r": {
        "window": P(500, "int", "innovations (epochs) in the sliding R estimate", lo=2),
        "form": P("paper", "str", "R estimate: paper (C_v + H P+ H^T, as printed), innovation "
                                  "(C_v - H P- H^T) or residual (C_r + H P+ H^T)",
                  choices=("paper", "innovation", "residual")),
        "floor_code_m2": P(10.0, "float", "lower limit of the code R", lo=1e-9),
        "floor_carrier_m2s2": P(1.0, "float", "lower limit of the carrier R", lo=1e-9),
    },
    "polynomial": {
        "position_taps": P(3, "int", "PPF length K of the position predictor (degree 2)", lo=3, hi=8),
        "velocity_taps": P(2, "int", "PPF length K of the velocity predictor (degree 1)", lo=2, hi=8),
        "drift_taps": P(2, "int", "PPF length K of the clock-drift predictor (degree 1)", lo=2, hi=8),
        "chi2_threshold": P(25.0, "float", "manoeuvre detection threshold on the code / carrier "
                                           "innovation chi-square tags (0 = off)", lo=0.0),
        "q_manoeuvre_pos_m2": P(1.0, "float", "manoeuvre Q (added on a detection): position jump "
                                              "variance", lo=0.0),
        "q_manoeuvre_vel_m2s2": P(0.1, "float", "manoeuvre Q: velocity jump variance ((m/s)^2)", lo=0.0),
        "q_manoeuvre_acc_m2s4": P(1.0, "float", "manoeuvre Q: acceleration jump variance ((m/s^2)^2; "
                                                "detections repeat while a manoeuvre lasts)", lo=0.0),
        "q_manoeuvre_clock": P(0.01, "float", "manoeuvre Q: clock-drift jump variance ((m/s)^2)", lo=0.0),
        "adaptive_r": P(True, "bool", "residual-form adaptive R (R = C_r + H P H^T over "
                                      "vector.adaptive_r.window epochs)"),
    },
    "cv": {
        "q_velocity": P(1e-3, "float", "per-epoch velocity process noise sigma_v^2 ((m/s)^2)", lo=0.0),
        "q_position": P(0.1, "float", "per-epoch position process noise sigma_p^2 (m^2)", lo=0.0),
        "q_bias": P(1e-7, "float", "per-epoch clock-bias process noise sigma_b^2 (m^2)", lo=0.0),
        "q_drift": P(0.1, "float", "per-epoch clock-drift process noise sigma_d^2 ((m/s)^2)", lo=0.0),
        "psd": P(False, "bool", "read the four q values as continuous white-noise PSDs (Q = q T) "
                                "instead of per-epoch variances"),
    },
}


def check(v: Section, sigs: list):
    """vector.enabled only with signals the vector loops track."""
    if v.enabled and any(s not in VECTOR_SIGNALS for s in sigs):
        raise UserError(f"config key 'vector.enabled': the vector loops track {' and '.join(VECTOR_SIGNALS)} "
                        f"only, not {', '.join(s for s in sigs if s not in VECTOR_SIGNALS)}")
