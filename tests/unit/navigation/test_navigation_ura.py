"""The broadcast accuracy term of the rtklib weighting (receiver.navigation.pvt.broadcast_accuracy_m): the URA
table for GPS / QZSS / BeiDou, the SISA table for Galileo (a SISA index is not a URA index: reading index 107
through the URA table would give 6144 m and all but drop the Galileo satellites from a GPS + Galileo fix)."""
from dataclasses import replace
from pathlib import Path

import pytest

from receiver.navigation.pvt import SISA_NAPA_M, broadcast_accuracy_m
from receiver.sim.bds_constellation import bds_nominal_ephemerides
from receiver.sim.constellation import nominal_ephemerides
from receiver.sim.gal_constellation import gal_nominal_content

REPO = Path(__file__).resolve().parents[3]


def test_accuracy_by_system():
    gps, _ = nominal_ephemerides(REPO / "data/gps_nominal_constellation.yaml", 2300, 345600.0)
    bds, _ = bds_nominal_ephemerides(REPO / "data/bds_nominal_constellation.yaml", 2300, 345600.0)
    gal = gal_nominal_content(REPO / "data/gal_nominal_constellation.yaml", 2300, 345600.0)[1].eph
    # IS-GPS-200 URA bounds (index 0, 2, 15 = no prediction); BeiDou URAI uses the same table
    assert [broadcast_accuracy_m(replace(gps[3], ura_index=i)) for i in (0, 2, 15)] == [2.4, 4.85, 6144.0]
    assert broadcast_accuracy_m(replace(bds[11], ura_index=1)) == 3.4
    # Galileo SISA: 107 -> 2 m + 7 x 16 cm; 30 -> 30 cm; 255 (NAPA) and spare indices -> RTKLIB's 500 m
    assert broadcast_accuracy_m(replace(gal, ura_index=107)) == pytest.approx(3.12)
    assert broadcast_accuracy_m(replace(gal, ura_index=30)) == pytest.approx(0.30)
    assert broadcast_accuracy_m(replace(gal, ura_index=255)) == SISA_NAPA_M
    assert broadcast_accuracy_m(replace(gal, ura_index=200)) == SISA_NAPA_M
