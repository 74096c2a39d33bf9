"""Stage times (receiver/stagetimes.py, ``gnssrx run --timings``): nested stages count their own time only,
and the CLI table accounts for the run."""
import pytest

from repo_paths import ROOT, TOKYO_REC
from receiver import stagetimes


class _Clock:
    """A scripted clock: the test advances wall and CPU time by hand (no dependence on the machine's load)."""

    def __init__(self):
        self.wall = self.cpu = 0.0

    def perf_counter(self):
        return self.wall

    def process_time(self):
        return self.cpu

    def work(self, wall, cpu):
        self.wall += wall
        self.cpu += cpu


def test_nested_stages_count_their_own_time(monkeypatch):
    clock = _Clock()
    monkeypatch.setattr(stagetimes, "time", clock)
    times = stagetimes.StageTimes()
    with stagetimes.recording(times):
        with stagetimes.stage("outer"):
            clock.work(0.05, 0.05)
            with stagetimes.stage("inner"):
                clock.work(0.1, 0.1)
            with stagetimes.stage("inner"):
                clock.work(0.05, 0.0)              # wall without CPU (a sleep)
            clock.work(0.02, 0.01)
    t = times.table()
    assert list(t) == ["inner", "outer"]       # in the order they finished first
    (wi, ci, ni), (wo, co, no) = t["inner"], t["outer"]
    assert ni == 2 and no == 1
    assert wi == pytest.approx(0.15) and ci == pytest.approx(0.1)     # the sleep is wall, not CPU
    assert wo == pytest.approx(0.07) and co == pytest.approx(0.06)    # outer without inner
    times.add("x", 1.0, 0.5)
    assert times.table()["x"] == (1.0, 0.5, 1)
    assert "sum of stages" in times.text()


def test_stages_outside_a_recording_go_nowhere(monkeypatch):
    """Each recording owns its times: a stage outside any recording, or inside another one, does not add
    to them."""
    clock = _Clock()
    monkeypatch.setattr(stagetimes, "time", clock)
    a, b = stagetimes.StageTimes(), stagetimes.StageTimes()
    with stagetimes.stage("loose"):
        clock.work(1.0, 1.0)
    with stagetimes.recording(a):
        with stagetimes.stage("s"):
            clock.work(0.5, 0.5)
        with stagetimes.recording(b):
            with stagetimes.stage("s"):
                clock.work(0.25, 0.25)
        with stagetimes.stage("s"):
            clock.work(0.5, 0.5)
    assert a.table() == {"s": (pytest.approx(1.0), pytest.approx(1.0), 2)}
    assert b.table() == {"s": (pytest.approx(0.25), pytest.approx(0.25), 1)}


def test_cli_timings_table_accounts_for_the_run(tmp_path):
    if not TOKYO_REC.exists():
        pytest.skip("../shared/data reference recording absent")
    from click.testing import CliRunner

    from receiver.cli import main
    r = CliRunner().invoke(main, [
        "run", str(ROOT / "configs" / "gpssim_static_tokyo.yaml"), "--input", str(TOKYO_REC),
        "-o", str(tmp_path / "x.h5"), "-q", "--timings", "--set", "input.duration_s=0.5",
        "--set", "acquisition.prns=[10, 23]"])
    assert r.exit_code == 0, r.output + r.stderr
    rows = {}
    for line in r.stderr.splitlines()[1:]:
        name, rest = line[:22].strip(), line[22:].split()
        rows[name] = [float(v) for v in rest[:2]]
    for name in ("imports", "open input", "acquisition", "tracking", "write", "sum of stages", "whole process"):
        assert name in rows, r.stderr
    assert rows["acquisition"][1] > 0 and rows["tracking"][0] > 0
    # the stages cover the process (CliRunner runs inside pytest: the whole process is far older)
    assert rows["sum of stages"][0] <= rows["whole process"][0]
    assert rows["sum of stages"][1] <= rows["whole process"][1] + 1e-3
