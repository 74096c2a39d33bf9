"""Simulator blockage: total outages, ``prn: all`` and the random urban-canyon pattern (receiver/sim/blockage.py)."""
import h5py
import numpy as np
import pytest

from receiver.errors import UserError
from receiver.sim.blockage import KIND_RANDOM, KIND_TOTAL
from receiver.sim.scenario import load_scenario
from receiver.sim.simulate import _Simulator, simulate

from test_sim_helpers import read_if

PRNS = [1, 7, 11, 14, 15, 17, 24, 26, 29, 30]        # above 5 deg in Tokyo at this time (fig-8 scenarios)
BASE = {"time": {"gps_week": 2300, "tow_s": 345598.0, "seed": 3},
        "constellation": {"prns": PRNS},
        "receiver": {"lat_deg": 35.68, "lon_deg": 139.77},
        "frontend": {"format": "complex64", "noise": False, "sample_rate_hz": 2.0e5}}


def _scenario(duration, blockage, seed=3):
    sc = {k: dict(v) for k, v in BASE.items()}
    sc["time"].update(duration_s=duration, seed=seed)
    sc["blockage"] = blockage
    return sc


def _truth(path):
    with h5py.File(path, "r") as f:
        ts = f["receiver/time_s"][:]
        prns = [int(k[1:]) for k in f["satellites"]]
        vis = np.array([f["satellites"][f"G{p:02d}"]["visible"][:] for p in prns])
        el = np.array([f["satellites"][f"G{p:02d}"]["elevation_deg"][:] for p in prns])
        b = {k: f["blockage"][k][:] for k in ("prn", "start_s", "end_s", "kind")}
        attrs = dict(f["blockage"].attrs)
    return ts, prns, vis, el, b, attrs


def test_total_outage_removes_every_signal(tmp_path):
    sc = _scenario(1.0, {"total": [{"start_s": 0.3, "end_s": 0.6}],
                         "outages": [{"prn": "all", "start_s": 0.8, "end_s": 0.9},
                                     {"prn": 11, "start_s": 0.1, "end_s": 0.2}]})
    paths = simulate(sc, str(tmp_path / "total.bin"), progress=False)
    ts, prns, vis, el, b, _ = _truth(paths["truth"])
    above = el >= 5.0
    assert above.all(axis=1).sum() >= 8
    dark = ((ts >= 0.3) & (ts < 0.6)) | ((ts >= 0.8) & (ts < 0.9))
    assert not vis[:, dark].any()
    other = ~dark & ~((ts >= 0.1) & (ts < 0.2))
    assert np.array_equal(vis[:, other], above[:, other])
    assert not vis[prns.index(11), (ts >= 0.1) & (ts < 0.2)].any()
    # the recording itself: (noise off) exactly zero while every satellite is blocked, signal elsewhere
    x = read_if(paths["if"], "complex64")
    t = np.arange(x.size) / 2.0e5
    for a, e in ((0.3, 0.6), (0.8, 0.9)):
        inside = (t > a + 0.002) & (t < e - 0.002)
        assert np.max(np.abs(x[inside])) == 0.0
        near = (t > a - 0.05) & (t < a - 0.002)
        assert np.min(np.abs(x[near])) >= 0.0 and np.mean(np.abs(x[near])) > 0.0
    assert np.mean(np.abs(x[(t > 0.65) & (t < 0.75)])) > 0.0
    # the truth's /blockage lists the windows: two totals (prn 0) and the single-satellite outage
    tot = b["kind"] == KIND_TOTAL
    assert sorted(zip(b["start_s"][tot], b["end_s"][tot])) == [(0.3, 0.6), (0.8, 0.9)]
    assert set(b["prn"][tot]) == {0}
    assert list(b["prn"][~tot]) == [11]


@pytest.mark.slow
@pytest.mark.parametrize("seed", [3, 4, 5])
def test_random_blockage_urban_canyon(tmp_path, seed):
    sc = _scenario(12.0, {"random": {"enabled": True, "start_s": 1.0}}, seed=seed)
    paths = simulate(sc, str(tmp_path / f"canyon{seed}.bin"), progress=False)
    ts, prns, vis, el, b, attrs = _truth(paths["truth"])
    win = ts >= 1.0
    assert vis[:, ~win].all()                           # no random blockage before start_s
    n_vis = vis.sum(axis=0)
    frac = np.mean(n_vis[win] >= 4)
    assert 0.62 <= frac <= 0.78, frac                    # at least 4 visible ~70 % of the time
    assert n_vis[win].min() < 4 and n_vis[win].max() > 4
    # each satellite's blocked spells (truth rows, 10 ms) last 0.2..5 s unless cut by the window end
    n_spells = 0
    for i in range(len(prns)):
        blocked = np.concatenate(([0], (~vis[i]).astype(np.int8), [0]))
        starts = np.nonzero(np.diff(blocked) == 1)[0]
        ends = np.nonzero(np.diff(blocked) == -1)[0]
        n_spells += starts.size
        for a, e in zip(starts, ends):
            dur = (e - a) * 0.01
            assert dur <= 5.0 + 0.011
            if e < ts.size:
                assert dur >= 0.2 - 0.011
    assert n_spells >= 2 * len(prns)                     # ~2.5 s blockages, ~2 s gaps: several per satellite
    # the /blockage table is what the truth visibility shows
    assert set(b["kind"]) == {KIND_RANDOM}
    assert attrs["random_start_s"] == 1.0 and attrs["random_end_s"] == 12.0
    assert 0.6 <= attrs["random_fraction"] <= 0.8
    for i, p in enumerate(prns):
        sel = b["prn"] == p
        inside = np.zeros(ts.size, bool)
        for a, e in zip(b["start_s"][sel], b["end_s"][sel]):
            inside |= (ts >= a) & (ts < e)
        assert np.array_equal(vis[i], ~inside & (el[i] >= 5.0))


def _pattern(seed, random_seed=None):
    r = {"enabled": True, "start_s": 5.0, "end_s": 60.0}
    if random_seed is not None:
        r["seed"] = random_seed
    sim = _Simulator(load_scenario(_scenario(60.0, {"random": r}, seed=seed)))
    return sim.blockage.table()


def test_random_blockage_length_distributions():
    sc = _scenario(400.0, {"random": {"enabled": True, "start_s": 0.0}})
    uni = _Simulator(load_scenario(sc)).blockage.table()
    sc["blockage"]["random"]["distribution"] = "loguniform"
    log = _Simulator(load_scenario(sc)).blockage.table()
    du, dl = uni[2] - uni[1], log[2] - log[1]
    du, dl = du[uni[2] < 400.0], dl[log[2] < 400.0]            # not cut by the end of the window
    assert du.min() >= 0.2 - 1e-9 and du.max() <= 5.0 + 1e-9 and dl.min() >= 0.2 - 1e-9
    assert abs(np.mean(du) - 2.6) < 0.2                          # uniform on [0.2, 5]
    assert abs(np.mean(dl) - 4.8 / np.log(25.0)) < 0.15          # log-uniform: (b - a) / ln(b / a) = 1.49
    assert abs(np.median(dl) - 1.0) < 0.15                       # geometric mean sqrt(0.2 * 5) = 1


def test_random_blockage_seeding():
    a, b = _pattern(1), _pattern(1)
    assert all(np.array_equal(x, y) for x, y in zip(a, b))
    c = _pattern(2)
    assert not np.array_equal(a[1][:20], c[1][:20])
    # an explicit random.seed fixes the pattern whatever the scenario seed
    d, e = _pattern(1, random_seed=9), _pattern(2, random_seed=9)
    assert all(np.array_equal(x, y) for x, y in zip(d, e))
    # long window: the fraction of time with >= 4 satellites is met closely (computed here from the table)
    t = np.arange(5.0, 60.0, 0.005)
    vis = np.ones((len(PRNS), t.size), bool)
    for p, s, en in zip(*a[:3]):
        vis[PRNS.index(p)] &= ~((t >= s) & (t < en))
    assert abs(np.mean(vis.sum(axis=0) >= 4) - 0.7) < 0.02


@pytest.mark.parametrize("blockage, msg", [
    ({"outages": [{"prn": "some", "start_s": 1, "end_s": 2}]}, "blockage.outages[0].prn"),
    ({"total": [{"start_s": 3, "end_s": 2}]}, "blockage.total[0]"),
    ({"total": [{"prn": 3, "start_s": 1, "end_s": 2}]}, "blockage.total[0]"),
    ({"random": {"enabled": True, "min_duration_s": 2.0, "max_duration_s": 1.0}}, "max_duration_s"),
    ({"random": {"enabled": True, "start_s": 50.0}}, "blockage.random.end_s"),
    ({"random": {"enabled": True, "min_visible": 12}}, "blockage.random.min_visible"),
    ({"random": {"enabled": True, "colour": 1}}, "blockage.random.colour"),
])
def test_bad_blockage_is_a_user_error(blockage, msg):
    with pytest.raises(UserError, match=msg.replace("[", r"\[").replace("]", r"\]")):
        _Simulator(load_scenario(_scenario(20.0, blockage)))


def test_outage_scenarios_as_documented():
    """configs/scenarios/outage_fig8*.yaml and urban_canyon_fig8.yaml: what their comments promise."""
    sim = _Simulator(load_scenario("configs/scenarios/outage_fig8.yaml"))
    assert sim.prns == PRNS and sim.duration == 185.0
    assert sim.blockage.total == [(50.0, 51.0), (70.0, 73.0), (95.0, 103.0), (125.0, 155.0)]
    short = _Simulator(load_scenario("configs/scenarios/outage_fig8_short.yaml"))
    assert short.blockage.total == [(12.0, 13.0), (20.0, 23.0)]
    canyon = _Simulator(load_scenario("configs/scenarios/urban_canyon_fig8.yaml"))
    r = canyon.blockage.random
    assert (r.t0, r.t1) == (45.0, 150.0) and abs(r.fraction - 0.7) < 0.01
    prn, a, e, _ = canyon.blockage.table()
    assert a.min() >= 45.0 and np.all(e - a <= 5.0 + 1e-9)
    assert set(prn) == set(PRNS)


def test_simulate_cli_summarises_the_blockage(tmp_path, monkeypatch):
    import yaml
    from click.testing import CliRunner
    from receiver.cli import main
    monkeypatch.chdir(tmp_path)
    sc = _scenario(3.0, {"total": [{"start_s": 0.5, "end_s": 1.0}],
                         "outages": [{"prn": 7, "start_s": 0.2, "end_s": 0.4}],
                         "random": {"enabled": True, "start_s": 1.5, "min_duration_s": 0.1,
                                    "max_duration_s": 0.5}})
    (tmp_path / "sc.yaml").write_text(yaml.safe_dump(sc))
    res = CliRunner().invoke(main, ["simulate", "sc.yaml", "-o", "x.bin"])
    assert res.exit_code == 0, res.output
    line = next(x for x in res.output.splitlines() if x.startswith("blockage:"))
    assert "1 total outages (0.5-1 s)" in line and "1 satellite outages" in line
    assert "random blockages in 1.5-3 s, >= 4 satellites visible" in line
