"""RINEX 3.04 observation export of a dual-frequency run (receiver.export.rinex_obs, second band): the C5Q / L5Q /
D5Q / S5Q codes of GPS L5 and Galileo E5a only for the systems whose band the run has, the band's fields from its
/observables_<tag> table on the line of the first band's row with the same receiver time and satellite, blanks
for satellites without a band measurement, the band's LLI, and the single-band file unchanged."""
import h5py
import numpy as np

from receiver.export.rinex_obs import LLI_HALF_CYCLE, LLI_LOSS, band_tables, write_rinex_obs
from receiver.gnss.geodesy import ecef2lla, lla2ecef
from receiver.runfile.reader import RunData
from receiver.runfile.record import FIX_DTYPE, OBS_DTYPE

TIMES = (30.0, 30.1, 30.2, 30.3)


def _run(tmp_path, sats, system="G", name="dual.h5"):
    x = np.array(lla2ecef(35.68, 139.77, 10.0))
    fx = np.zeros(len(TIMES), FIX_DTYPE)
    obs = np.zeros(len(TIMES) * len(sats), OBS_DTYPE)
    for k, t in enumerate(TIMES):
        lat, lon, h = ecef2lla(x)
        fx[k] = (2300, 345600.0 + t, t, x, np.zeros(3), 12.0, 0.1, len(sats), 1.2, 0.7, 1.0, 1.4, 0, lat, lon, h, 1)
        for j, p in enumerate(sats):
            obs[k * len(sats) + j] = (k, 2300, 345600.0 + t, t, p, 2.1e7 + 1e5 * j + 10 * k, 0.0, -1000.0 + j,
                                      1e6 + j + 100 * k, 44.0, 10.0 + t, 1, 1, 40.0, 100.0, 0.1)
    return RunData(path=str(tmp_path / name), attrs={"system": system}, config={}, fixes=fx, obs=obs,
                   _iono_done=True)


def _band(run, prns, lock=None, half=None):
    """Band rows copied from the first band's rows of ``prns`` (as receiver.navigation.ionofree builds them),
    with band values of their own."""
    b = run.obs[np.isin(run.obs["prn"], prns)].copy()
    b["pseudorange_m"] += 7.25
    b["carrier_phase_cycles"] = 0.75e6 + np.arange(len(b))
    b["doppler_hz"] = -747.5 - np.arange(len(b))
    b["cn0_dbhz"] = 41.0
    b["lock_time_s"] = 5.0 if lock is None else lock
    b["half_cycle_resolved"] = 1 if half is None else half
    return b


def _parse(path):
    text = path.read_text().splitlines()
    end = next(i for i, ln in enumerate(text) if "END OF HEADER" in ln)
    head = text[:end + 1]
    types = {ln[0]: ln[7:60].split() for ln in head if ln[60:].strip() == "SYS / # / OBS TYPES"}
    epochs, cur = [], None
    for ln in text[end + 1:]:
        if ln.startswith(">"):
            cur = {}
            epochs.append(cur)
        else:
            cur[ln[:3]] = ln[3:]
    return head, types, epochs


def _value(line, k):
    """(value or None, LLI char, SSI char) of observation field k of a satellite line (after its label)."""
    f = line[16 * k:16 * k + 16].ljust(16)
    return (float(f[:14]) if f[:14].strip() else None), f[14], f[15]


def test_header_codes_only_for_the_band_system(tmp_path):
    """A mixed G + E run with only the L5 band: GPS gets C5Q.. and an L5Q phase-shift line, Galileo keeps E1."""
    run = _run(tmp_path, [3, 305], system="M")            # G03, E05 (Galileo keyed 300 + PRN)
    out = tmp_path / "m.obs"
    write_rinex_obs(out, run, bands={"l5": _band(run, [3])})
    head, types, _ = _parse(out)
    assert types == {"G": ["C1C", "L1C", "D1C", "S1C", "C5Q", "L5Q", "D5Q", "S5Q"],
                     "E": ["C1C", "L1C", "D1C", "S1C"]}
    shifts = [ln[:60].split() for ln in head if ln[60:].strip() == "SYS / PHASE SHIFT"]
    assert shifts == [["G", "L1C", "0.00000"], ["G", "L5Q", "0.00000"], ["E", "L1C", "0.00000"]]
    counts = {ln[3:6]: ln[6:60].split() for ln in head if ln[60:].strip() == "PRN / # OF OBS"}
    assert counts == {"G03": ["4"] * 8, "E05": ["4"] * 4}
    assert any("GPS L5 (Q5 pilot)" in ln and "COMMENT" in ln for ln in head)


def test_galileo_e5a_codes(tmp_path):
    run = _run(tmp_path, [305, 311], system="M")
    out = tmp_path / "e.obs"
    write_rinex_obs(out, run, bands={"e5a": _band(run, [305, 311])})
    _, types, epochs = _parse(out)
    assert types == {"E": ["C1C", "L1C", "D1C", "S1C", "C5Q", "L5Q", "D5Q", "S5Q"]}
    assert _value(epochs[0]["E11"], 4)[0] == float(f"{2.1e7 + 1e5 + 7.25:.3f}")


def test_fields_are_the_band_table_and_blanks_for_missing_satellites(tmp_path):
    run = _run(tmp_path, [3, 8, 12])
    band = _band(run, [3, 12])
    band = band[~((band["prn"] == 12) & (band["time_s"] == TIMES[2]))]     # G12 without L5 at the third epoch
    out = tmp_path / "g.obs"
    write_rinex_obs(out, run, bands={"l5": band})
    _, types, epochs = _parse(out)
    assert types["G"][4:] == ["C5Q", "L5Q", "D5Q", "S5Q"]
    assert len(epochs) == len(TIMES)
    for k, ep in enumerate(epochs):
        assert set(ep) == {"G03", "G08", "G12"}          # every L1 satellite keeps its line
        for sat, prn in (("G03", 3), ("G12", 12)):
            rows = band[(band["prn"] == prn) & (band["time_s"] == TIMES[k])]
            if not len(rows):
                assert ep[sat][64:].strip() == ""           # no band fields at all
                continue
            r = rows[0]
            c5, l5, d5, s5 = (_value(ep[sat], i) for i in range(4, 8))
            assert c5[0] == float(f"{r['pseudorange_m']:.3f}") and c5[2] == "6"        # SSI of 41 dB-Hz
            assert l5[0] == float(f"{-r['carrier_phase_cycles']:.3f}") and l5[1] == " "
            assert d5[0] == float(f"{r['doppler_hz']:.3f}") and s5[0] == 41.0
            # the L1 fields unchanged
            assert _value(ep[sat], 0)[0] == float(f"{2.1e7 + 1e5 * [3, 8, 12].index(prn) + 10 * k:.3f}")
        assert ep["G08"][64:].strip() == ""                 # L1 only
    # back after a missing L5 epoch with a lock time (5 s) longer than the gap: no loss flag
    assert _value(epochs[3]["G12"], 5)[1] == " "


def test_band_lli_from_its_own_lock_and_half_cycle(tmp_path):
    run = _run(tmp_path, [3])
    lock = np.array([2.0, 0.05, 0.15, 0.25])              # band lock restarted between the first two epochs
    half = np.array([0, 1, 1, 1])
    out = tmp_path / "lli.obs"
    write_rinex_obs(out, run, bands={"l5": _band(run, [3], lock=lock, half=half)})
    _, _, epochs = _parse(out)
    lli = [_value(ep["G03"], 5)[1] for ep in epochs]
    assert lli == [str(LLI_HALF_CYCLE), str(LLI_LOSS), " ", " "]
    assert [_value(ep["G03"], 1)[1] for ep in epochs] == [" "] * 4       # L1C: its own lock time, no flag


def test_no_band_same_file_and_band_tables_from_the_run_file(tmp_path):
    """Without band rows the file is the single-band one (apart from the creation date); with a run file that
    has /observables_l5 band_tables reads it (the default of write_rinex_obs)."""
    run = _run(tmp_path, [3, 8])
    a, b = tmp_path / "a.obs", tmp_path / "b.obs"
    write_rinex_obs(a, run)                        # no file behind the run: no bands
    write_rinex_obs(b, run, bands={})
    strip = [ln for ln in a.read_text().splitlines() if "PGM / RUN BY" not in ln]
    assert strip == [ln for ln in b.read_text().splitlines() if "PGM / RUN BY" not in ln]
    assert all(len(ln) <= 3 + 4 * 16 for ln in strip if ln[:1] == "G" and ln[1:3].isdigit())

    band = _band(run, [8])
    with h5py.File(run.path, "w") as h:
        g = h.create_group("observables_l5")
        for name in OBS_DTYPE.names:
            g[name] = band[name]
    run.groups = ["navigation", "observables", "observables_l5"]
    got = band_tables(run)
    assert list(got) == ["l5"] and np.array_equal(got["l5"], band)
    write_rinex_obs(a, run)
    _, types, epochs = _parse(a)
    assert types["G"][4:] == ["C5Q", "L5Q", "D5Q", "S5Q"]
    assert epochs[0]["G03"][64:].strip() == "" and _value(epochs[0]["G08"], 4)[0] is not None


def test_signal_letters_once_per_system():
    """A Galileo E1 + E5a run is a Galileo run (its assisting RINEX records keyed by PRN, as its observables):
    the second band adds no system, so the navigation file of an assisted dual-frequency run has its records."""
    def letters(signals):
        return RunData(path="x.h5", attrs={}, config={"signals": signals}, fixes=np.zeros(0, FIX_DTYPE),
                       obs=np.zeros(0, OBS_DTYPE)).signal_letters()
    assert letters(["gal_e1", "gal_e5a"]) == ["E"]
    assert letters(["gps_l1ca", "gps_l5"]) == ["G"]
    assert letters(["gps_l1ca", "gal_e1", "gps_l5", "gal_e5a"]) == ["G", "E"]
