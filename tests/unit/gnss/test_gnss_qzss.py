"""QZSS L1 C/A (PRN 193..202 = J01..J10): codes against IS-QZSS, labels, RINEX J records, and a short
simulated GPS+QZSS recording acquired and tracked through the GPS chain."""
from dataclasses import fields

import h5py
import numpy as np
import pytest

from receiver.gnss.satid import parse_label, sat_label, sat_system
from receiver.gnss.signals import GPS_PRNS, QZSS_PRNS, _g_sequences, ca_code, ca_code_bits

from repo_paths import ROOT as REPO

# IS-QZSS-PNT, Table 3.2.2-2 (L1C/A code phase assignments): PRN, G2 delay (chips), initial G2 setting
# (octal), first 10 chips (octal; first digit = first chip)
QZSS_TABLE = [
    (193, 339, 0o1050, 0o0727), (194, 208, 0o1607, 0o0170), (195, 711, 0o1747, 0o0030),
    (196, 189, 0o1305, 0o0472), (197, 263, 0o0540, 0o1237), (198, 537, 0o1363, 0o0414),
    (199, 663, 0o0727, 0o1050), (200, 942, 0o0147, 0o1630), (201, 173, 0o1206, 0o0571),
    (202, 900, 0o1045, 0o0732),
]
# IS-GPS-200H Table 6-I (sheet 2): SBAS PRN 120..125, the same G2-delay construction the QZSS codes use
# (PRN, G2 delay, first 10 chips octal)
SBAS_TABLE = [(120, 145, 0o0671), (121, 175, 0o0536), (122, 52, 0o1510), (123, 21, 0o1545),
              (124, 237, 0o0160), (125, 235, 0o0701)]


def _first10(bits):
    return int("".join(str(int(b)) for b in bits[:10]), 2)


@pytest.mark.parametrize("prn,delay,init,first", QZSS_TABLE)
def test_qzss_first_chips_match_is_qzss(prn, delay, init, first):
    bits = ca_code_bits(prn)
    assert _first10(bits) == first
    assert first ^ 0o1777 == init          # G1 starts all ones: first chips = complement of the G2 setting
    assert len(bits) == 1023


@pytest.mark.parametrize("prn,delay,first", SBAS_TABLE)
def test_g2_delay_construction_matches_icd_sbas_rows(prn, delay, first):
    g1, g2 = _g_sequences()
    assert _first10(g1 ^ np.roll(g2, delay)) == first


def test_qzss_codes_are_gold_codes_of_the_gps_family():
    qz = [ca_code(p).astype(np.float64) for p in QZSS_PRNS]
    gps = [ca_code(p).astype(np.float64) for p in GPS_PRNS[:8]]
    fq = [np.fft.fft(c) for c in qz]
    for i, a in enumerate(fq):
        assert abs(qz[i].sum()) in (1.0, 63.0, 65.0)
        auto = np.fft.ifft(a * np.conj(a)).real
        assert auto[0] == pytest.approx(1023) and np.max(np.abs(auto[1:])) <= 65 + 1e-9
        for c in gps + qz[:i]:
            xc = np.fft.ifft(a * np.conj(np.fft.fft(c))).real
            assert np.max(np.abs(xc)) <= 65 + 1e-9


def test_labels():
    assert sat_label(5) == "G05" and sat_label(193) == "J01" and sat_label(202) == "J10"
    assert sat_label(12, "C") == "C12" and sat_system(199) == "J" and sat_system(32) == "G"
    assert parse_label("J07") == ("J", 199) and parse_label("C05") == ("C", 5)


def test_rinex3_qzss_records_round_trip(tmp_path):
    from receiver.gnss.ephemeris import Ephemeris
    from receiver.gnss.rinex import read_rinex_nav, write_rinex_nav
    from receiver.sim.constellation import nominal_ephemerides
    ephs, iono = nominal_ephemerides(REPO / "data/qzss_nominal_constellation.yaml", 2300, 345600.0)
    gps, _ = nominal_ephemerides(REPO / "data/gps_nominal_constellation.yaml", 2300, 345600.0)
    both = {**{p: [e] for p, e in ephs.items()}, 3: [gps[3]]}
    out = tmp_path / "mixed.rnx"
    write_rinex_nav(out, both, iono)
    text = out.read_text()
    assert "M: MIXED" in text.splitlines()[0]
    assert sum(ln.startswith("J") for ln in text.splitlines()) == len(ephs)
    assert "J01 " in text and "J07 " in text and "G03 " in text
    back, _ = read_rinex_nav(out)
    assert sorted(back) == sorted(both)
    for prn, (e,) in both.items():
        b = back[prn][0]
        for f in fields(Ephemeris):
            if f.name not in ("aodo",):
                assert getattr(b, f.name) == pytest.approx(getattr(e, f.name), rel=1e-11, abs=1e-20), f.name


# ------------------------------------------------------------------------------- simulated recording
@pytest.fixture(scope="module")
def qzss_run(tmp_path_factory):
    from receiver.schema import load_receiver_config
    from receiver.pipeline import run
    from receiver.sim.simulate import simulate
    d = tmp_path_factory.mktemp("qzss")
    out = d / "qz.bin"
    simulate({"time": {"gps_week": 2300, "tow_s": 345600.0, "duration_s": 1.5, "seed": 5},
              "constellation": {"source": "embedded", "qzss": True, "prns": [193, 199, 7]},
              "cn0": {"mode": "constant", "dbhz": 45.0}, "clock": {"noise": "none"},
              "frontend": {"sample_rate_hz": 2.6e6, "if_hz": 0.0, "format": "int8_iq"}},
             str(out), progress=False)
    cfg = load_receiver_config(REPO / "configs/default.yaml",
                               [("input.path", str(out)), ("input.format", "int8_iq"),
                                ("input.sample_rate_hz", 2.6e6), ("input.if_hz", 0.0),
                                ("output.path", str(d / "qz.h5")), ("acquisition.prns", [7, 193, 196, 199]),
                                ("navigation.enabled", False)])
    summary = run(cfg, quiet=True, log=lambda *a: None)
    return summary, d / "qz.h5", d / "qz.truth.h5"


@pytest.mark.slow
def test_qzss_satellites_acquired_and_tracked_as_jnn(qzss_run):
    summary, run_h5, truth_h5 = qzss_run
    assert summary.tracked == [7, 193, 199]          # J04 (196) is not simulated: not detected
    assert "J01(" in summary.text() and "J07(" in summary.text() and "G07(" in summary.text()
    with h5py.File(run_h5, "r") as f, h5py.File(truth_h5, "r") as t:
        assert sorted(f["channels"]) == ["G07", "J01", "J07"]
        assert f["channels"]["J01"].attrs["prn"] == 193
        for name in ("J01", "J07"):
            g = f["channels"][name]
            assert g["cn0_dbhz"][-1] > 41.0                                  # 45 dB-Hz simulated
            assert abs(g["doppler_hz"][-1] - t["satellites"][name]["doppler_hz"][-1]) < 5.0


def test_config_rejects_prns_the_signal_has_no_code_for():
    from receiver.schema import load_receiver_config
    from receiver.errors import UserError
    with pytest.raises(UserError, match="no PRN 150"):
        load_receiver_config(REPO / "configs/default.yaml", [("acquisition.prns", [1, 150])])
    with pytest.raises(UserError, match="no PRN 64"):
        load_receiver_config(REPO / "configs/default.yaml", [("signal", "bds_b1i"), ("acquisition.prns", [64])])
    # the vector loops track B1I too (tests/system/test_vector_gnss.py)
    assert load_receiver_config(REPO / "configs/carrier_bds_b1i.yaml", [("vector.enabled", True)]).vector.enabled
