"""Multi-system outputs on a synthetic run: RINEX 3 mixed observation header and labels (G, J, C), NMEA
talker GN with one GSA per system, satellite labels."""
import numpy as np

from receiver.export.nmea import checksum, nmea_lines
from receiver.export.rinex_obs import write_rinex_obs
from receiver.gnss.geodesy import ecef2lla, lla2ecef
from receiver.runfile.reader import RunData
from receiver.runfile.record import FIX_DTYPE, OBS_DTYPE

SATS = [1, 7, 193, 401, 412]             # G01, G07, J01, C01, C12 (BeiDou keyed 400 + PRN)


def _run(tmp_path, system="G"):
    x = np.array(lla2ecef(35.68, 139.77, 10.0))
    fx = np.zeros(2, FIX_DTYPE)
    obs = np.zeros(2 * len(SATS), OBS_DTYPE)
    for k in range(2):
        lat, lon, h = ecef2lla(x)
        fx[k] = (2300, 345600.0 + 0.1 * k, 30.0 + 0.1 * k, x, np.zeros(3), 12.0, 0.1, len(SATS), 1.2, 0.7, 1.0,
                 1.4, 0, lat, lon, h, 1)
        for j, p in enumerate(SATS):
            obs[k * len(SATS) + j] = (k, 2300, 345600.0 + 0.1 * k, 30.0 + 0.1 * k, p, 2.1e7 + 1e5 * j, 0.0,
                                      -1000.0 + j, 1e6 + j, 44.0, 10.0, 1, 1, 40.0 + j, 100.0 + 10 * j, 0.1)
    return RunData(path=str(tmp_path / "multi.h5"), attrs={"system": system}, config={}, fixes=fx, obs=obs,
                   _iono_done=True)      # no file behind it: no stored iono/UTC (leap seconds from the table)


def test_mixed_rinex_header_and_labels(tmp_path):
    out = tmp_path / "multi.obs"
    info = write_rinex_obs(out, _run(tmp_path))
    text = out.read_text().splitlines()
    assert text[0][40:41] == "M"
    types = {ln[0]: ln[7:60].split() for ln in text if ln[60:].strip() == "SYS / # / OBS TYPES"}
    assert types == {"G": ["C1C", "L1C", "D1C", "S1C"], "C": ["C2I", "L2I", "D2I", "S2I"],
                     "J": ["C1C", "L1C", "D1C", "S1C"]}
    body = text[next(i for i, ln in enumerate(text) if "END OF HEADER" in ln) + 1:]
    assert [ln[:3] for ln in body[1:6]] == ["G01", "G07", "J01", "C01", "C12"]
    assert info["epochs"] == 2


def test_nmea_gn_talker_and_one_gsa_per_system(tmp_path):
    lines = nmea_lines(_run(tmp_path))
    for ln in lines:
        body, cs = ln[1:].split("*")
        assert checksum(body) == cs
    first = lines[:7]
    assert first[0].startswith("$GNGGA") and first[1].startswith("$GNRMC")
    gsa = [ln for ln in first if ln[3:6] == "GSA"]
    assert len(gsa) == 2
    fields = [g.split("*")[0].split(",") for g in gsa]
    by_sys = {f[-1]: [v for v in f[3:15] if v] for f in fields}
    assert by_sys == {"4": ["01", "12"], "1": ["01", "07", "193"]}
    assert any(ln.startswith("$GBGSV") for ln in first) and any(ln.startswith("$GPGSV") for ln in first)


def test_single_system_talkers(tmp_path):
    run = _run(tmp_path, "C")
    run.obs["prn"] = np.where(run.obs["prn"] > 400, run.obs["prn"] - 400, run.obs["prn"] % 30 + 20)
    lines = nmea_lines(run)
    assert lines[0].startswith("$GBGGA") and lines[2].startswith("$GBGSA") and lines[3].startswith("$GBGSV")
