"""Plain-numpy synthetic GPS L1 C/A signals for unit tests (independent of receiver.sim).

Convention (as in the receiver): a satellite with positive Doppler is exp(+j 2 pi f_D t) in I + jQ;
C/N0 = A^2 fs / sigma^2 with complex noise of variance sigma^2 per sample.
"""
import numpy as np

from receiver.gnss.signals import CA_CHIP_RATE, CA_CODE_LEN, L1_HZ, ca_code


def make_signal(sats, fs=2.6e6, duration_s=1.0, noise_sigma=1.0, seed=0, if_hz=0.0, real=False):
    """sats: list of dicts prn, doppler_hz, code_phase_chips (at sample 0), cn0_dbhz, bits (optional
    array of +/-1 at 50 bps, the first bit starting at code period `bit_start_ms`)."""
    n = int(round(duration_s * fs))
    rng = np.random.default_rng(seed)
    t = np.arange(n) / fs
    x = np.zeros(n, np.complex128)
    for s in sats:
        a = np.sqrt(10 ** (s["cn0_dbhz"] / 10) * noise_sigma ** 2 / fs)
        rate = CA_CHIP_RATE * (1 + s["doppler_hz"] / L1_HZ)
        chips = s.get("code_phase_chips", 0.0) + t * rate
        code = ca_code(s["prn"])[np.floor(chips).astype(np.int64) % CA_CODE_LEN]
        sig = a * code * np.exp(1j * (2 * np.pi * (if_hz + s["doppler_hz"]) * t + s.get("phase_rad", 0.0)))
        if "bits" in s:
            period = np.floor(chips / CA_CODE_LEN).astype(np.int64) - s.get("bit_start_ms", 0)
            bit_idx = np.floor_divide(period, 20) % len(s["bits"])
            sig = sig * np.asarray(s["bits"])[bit_idx]
        x += sig
    if real:
        x = x.real * np.sqrt(2)
        noise = rng.normal(scale=noise_sigma, size=n)
        return (x + noise).astype(np.float32)
    noise = (rng.normal(size=n) + 1j * rng.normal(size=n)) * (noise_sigma / np.sqrt(2))
    return (x + noise).astype(np.complex64)


def gauss_markov(n, sigma, tau_s, rate_hz, rng):
    """A DLL-like code error: first-order Gauss-Markov sequence of n epochs at rate_hz, standard deviation
    sigma, correlation time tau_s (seconds)."""
    a = np.exp(-1.0 / (rate_hz * tau_s))
    e = np.zeros(n)
    w = rng.normal(scale=sigma * np.sqrt(1 - a * a), size=n)
    e[0] = rng.normal(scale=sigma)
    for k in range(1, n):
        e[k] = a * e[k - 1] + w[k]
    return e
