"""Galileo E1 in the navigation engine's per-satellite memory (receiver.navigation.channel.ChannelNav): records
of 4-ms code periods whose E1-B prompts carry a genuine I/NAV stream (receiver.gnss.gal_inav.InavStream, with
a few symbol errors) give the decoded ephemeris and the transmit time of every record, equal to the GST (=
GPS time here) at which the simulated satellite sent that code period."""
import numpy as np
import pytest

from receiver.gnss.gal_inav import GST_WEEK_OFFSET, InavStream, quantize_gal
from receiver.gnss.registry import get_signal
from receiver.navigation.channel import ChannelNav
from receiver.runfile.record import EPOCH_DTYPE, STATE_BIT_SYNC
from receiver.sim.gal_constellation import gal_nominal_content

from repo_paths import ROOT

pytestmark = pytest.mark.slow          # (numba compiles, seconds of samples)
WEEK, TOW0 = 2300, 345619.5
FS = 4.0e6
N = 4.0e-3 * FS


def _records(prn, seconds, first_period_of_week, rng):
    content = gal_nominal_content(ROOT / "data/gal_nominal_constellation.yaml", WEEK, TOW0)[prn]
    n = int(seconds / 4e-3)
    sym = InavStream(content, WEEK - GST_WEEK_OFFSET).signs(first_period_of_week + 1, n)
    soft = 1000.0 * sym * np.where(rng.random(n) < 0.03, -1.0, 1.0)          # 3 % symbol errors
    r = np.zeros(n, EPOCH_DTYPE)
    r["code_period"] = np.arange(1, n + 1)
    r["sample_index"] = (123 + np.arange(n) * N).astype(np.int64)
    r["time_s"] = r["sample_index"] / FS
    r["code_phase_chips"] = 0.02
    r["code_rate_hz"] = 1.023e6
    r["state"] = STATE_BIT_SYNC
    r["pll_lock"] = 1
    r["cn0_dbhz"] = 42.0
    r["integration_ms"] = 4
    r["prompt1_i"] = -soft          # any polarity: the page sync decides
    return r, content


@pytest.mark.parametrize("prn", [3, 18])
def test_inav_records_give_ephemeris_and_transmit_time(prn):
    rng = np.random.default_rng(prn)
    m0 = int(np.floor(TOW0 / 4e-3))              # 4-ms period of the week at the channel's period 0
    recs, content = _records(prn, 20.0, m0, rng)
    ch = ChannelNav(prn, WEEK, 0.0, FS, get_signal("gal_e1"))
    assert ch.period_s == 4e-3 and ch.bit_ms == 4
    for k in range(0, len(recs), 125):           # 0.5-s chunks, as the pipeline feeds them
        ch.add(recs[k:k + 125], 0)
    dec = ch.decoder
    assert dec.crc_failures == 0 and dec.pages_ok >= 8
    assert dec.ephemeris == quantize_gal(content.eph) and dec.week == WEEK
    assert ch.has_time and ch.polarity == 1
    for i in (len(recs) - 370, len(recs) - 200, len(recs) - 10):      # (the memory keeps the last 3 chunks)
        s = float(recs["sample_index"][i]) + 0.25 * N          # a quarter period into the epoch
        txrel = ch.measure(s)[0]
        true = (m0 + int(recs["code_period"][i])) * 4e-3 + (0.02 + 0.25 * N / FS * 1.023e6) / 1.023e6
        assert ch.tx_offset + txrel == pytest.approx(true, abs=1e-9)


def test_resume_keeps_the_decoded_data():
    rng = np.random.default_rng(1)
    recs, content = _records(3, 20.0, int(np.floor(TOW0 / 4e-3)), rng)
    ch = ChannelNav(3, WEEK, 0.0, FS, get_signal("gal_e1"))
    ch.add(recs, 0)
    eph = ch.decoder.ephemeris
    ch.suspend()
    ch.resume(continuous=False)
    assert not ch.has_time and ch.decoder.ephemeris is eph and ch.decoder.week == WEEK
    assert ch.decoder.pages_ok > 0
