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
    stagetimes.reset()
    with stagetimes.stage("outer"):
        clock.work(0.05, 0.05)
        with stagetimes.stage("inner"):
            clock.work(0.1, 0.1)
        with stagetimes.stage("inner"):
            clock.work(0.05, 0.0)              # wall without CPU (a sleep)
        clock.work(0.02, 0.01)
    t = stagetimes.table()
    assert list(t) == ["inner", "outer"]       # in the order they finished first
    (wi, ci, ni), (wo, co, no) = t["inner"], t["outer"]
    assert ni == 2 and no == 1
    assert wi == pytest.approx(0.15) and ci == pytest.approx(0.1)     # the sleep is wall, not CPU
    assert wo == pytest.approx(0.07) and co == pytest.approx(0.06)    # outer without inner
    stagetimes.add("x", 1.0, 0.5)
    assert stagetimes.table()["x"] == (1.0, 0.5, 1)
    assert "sum of stages" in stagetimes.text()
    stagetimes.reset()
    assert stagetimes.table() == {}


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
