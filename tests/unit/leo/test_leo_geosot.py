"""GeoSOT codes and the grid-search initial value (receiver.leo.geosot)."""
import numpy as np
import pytest

from receiver.gnss.geodesy import lla2ecef
from receiver.leo import geosot as G
from receiver.leo.config import load_scenario
from receiver.leo.constellation import Constellation
from receiver.leo.doppler import simulate


def test_code_fields_and_cell_sizes():
    code = int(G.encode(39.9042))                  # 39 deg 54' 15.12"
    assert (code >> 31) == 0
    assert (code >> 23) & 0xFF == 39
    assert (code >> 17) & 0x3F == 54
    assert (code >> 11) & 0x3F == 15
    assert abs((code & 0x7FF) / 2048 - 0.12) < 1 / 2048
    assert (int(G.encode(-0.5)) >> 31) == 1
    assert G.nominal_size_deg(9) == 1.0
    assert G.nominal_size_deg(15) == pytest.approx(1 / 60)
    assert G.nominal_size_deg(21) == pytest.approx(1 / 3600)
    assert G.nominal_size_deg(32) == pytest.approx(1 / 3600 / 2048)
    # level 1 = four 256-degree quadrants, level 0 = everything
    lo, hi, ok = G.prefix_extent(np.array([0, 1]), 1, 180.0)
    assert ok.all() and np.allclose(lo, [0, -180]) and np.allclose(hi, [180, 0])


def test_points_lie_in_their_cells_and_cells_nest():
    rng = np.random.default_rng(3)
    lat = rng.uniform(-89.9, 89.9, 300)
    lon = rng.uniform(-179.9, 179.9, 300)
    for level in (1, 5, 9, 10, 12, 14, 15, 17, 21, 25, 32):
        lp, op = G.cell_of(lat, lon, level)
        la0, la1, vla = G.prefix_extent(lp, level, 90.0)
        lo0, lo1, vlo = G.prefix_extent(op, level, 180.0)
        assert vla.all() and vlo.all()
        eps = 1e-9
        assert np.all((la0 - eps <= lat) & (lat <= la1 + eps))
        assert np.all((lo0 - eps <= lon) & (lon <= lo1 + eps))
        if level < 32:
            lp2, op2 = G.cell_of(lat, lon, level + 1)
            assert np.array_equal(lp2 >> 1, lp) and np.array_equal(op2 >> 1, op)
    code = G.quadtree_code(*G.cell_of(39.9, 116.4, 9), 9)
    assert code.startswith("G") and len(code) == 10 and set(code[1:]) <= set("0123")


def test_extended_minutes_do_not_exist():
    # one degree is extended to 64': at level 12 (8' cells) the last cell 56'-64' is cut at 60',
    # at level 13 (4' cells) the cell 60'-64' does not exist
    deg_cell = int(G.encode(39.0)) >> (32 - 9)
    kids12 = [(deg_cell << 3) | k for k in range(8)]
    lo, hi, ok = G.prefix_extent(np.array(kids12), 12, 90.0)
    assert ok.all()
    assert hi[7] == pytest.approx(40.0) and hi[7] - lo[7] == pytest.approx(4 / 60)
    assert hi[6] - lo[6] == pytest.approx(8 / 60)
    kids13 = [(deg_cell << 4) | k for k in range(16)]
    lo, hi, ok = G.prefix_extent(np.array(kids13), 13, 90.0)
    assert ok.tolist() == [True] * 15 + [False]
    cells = G.Cells(12, np.array([kids12[7]]), np.array([int(G.encode(116.2)) >> 20]))
    assert len(cells.children()) == 2                   # only the 56'-60' latitude half exists
    # same for seconds: level 18 (8" cells) inside one minute, the 60"-64" cell at level 19 is absent
    minute = int(G.encode(39.0 + 5 / 60)) >> (32 - 15)
    lo, hi, ok = G.prefix_extent(np.array([(minute << 4) | k for k in range(16)]), 19, 90.0)
    assert ok.tolist() == [True] * 15 + [False]


@pytest.fixture(scope="module")
def con():
    return Constellation.from_file()


@pytest.mark.parametrize("end_level,frac", [(15, (0.07, -0.05)), (18, (-0.06, 0.08)),
                                            (21, (0.03, 0.02))])
def test_grid_search_lands_in_the_truth_cell_on_noise_free_data(con, end_level, frac):
    # truth: a point in the inner fifth of a GeoSOT cell of the end level, on the searched surface.
    # (Near a cell edge the strongly anisotropic Doppler cost can favour the neighbour's centre: the
    # search returns the best centre, which is then not necessarily the truth cell.)
    lp, op = G.cell_of(39.95, 116.35, end_level)
    la0, la1, _ = G.prefix_extent(lp, end_level, 90.0)
    lo0, lo1, _ = G.prefix_extent(op, end_level, 180.0)
    lat = 0.5 * (la0 + la1) + frac[0] * (la1 - la0)
    lon = 0.5 * (lo0 + lo1) + frac[1] * (lo1 - lo0)
    cfg = load_scenario(None, [f"receiver.lat_deg={float(lat)}", f"receiver.lon_deg={float(lon)}",
                               "receiver.height_m=0", "measurement.noise_sigma_hz=0",
                               "receiver.freq_offset_hz=-420"])
    d = simulate(cfg, con)
    _, sp, sv, z = d.stacked()
    res = G.grid_search(sp, sv, z, d.carrier_hz, start_level=9, end_level=end_level, keep=32)
    truth_cell = G.cell_of(lat, lon, end_level)
    assert (res.lat_prefix, res.lon_prefix) == (int(truth_cell[0]), int(truth_cell[1]))
    assert res.level == end_level
    assert abs(res.freq_offset_hz + 420) < 2.0
    assert np.linalg.norm(res.ecef - lla2ecef(lat, lon, 0.0)) < res.cell_size_m


def test_search_region_contains_truth_and_is_smaller_than_the_boxes(con):
    d = simulate(load_scenario(None, []), con)
    _, sp, _, _ = d.stacked()
    region = G.search_region(sp, 9, 0.0, 10.0, 5.0)
    truth = G.cell_of(39.9042, 116.4074, 9)
    assert any((region.lat_p == truth[0]) & (region.lon_p == truth[1]))
    lat, lon = region.centres()
    assert 50 < len(region) < 5000
    assert np.all(np.abs(lat - 39.9) < 25)


def test_grid_search_rejects_bad_levels(con):
    from receiver.errors import UserError
    with pytest.raises(UserError):
        G.grid_search(np.zeros((3, 3)) + 7e6, np.ones((3, 3)), np.zeros(3), 1.6e9, 10, 9)
