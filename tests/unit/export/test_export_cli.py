"""``gnssrx export | report | info`` and the ``output.*`` switches of ``gnssrx run``."""
import json
import os

import pytest
from click.testing import CliRunner

from receiver.cli import main
from receiver.schema import load_receiver_config
from receiver.errors import UserError
from receiver.export import export_all, output_paths

from repo_paths import ROOT, TOKYO_META, TOKYO_REC


@pytest.fixture()
def linked(tokyo_run, tmp_path):
    h5 = tmp_path / "run.h5"
    os.symlink(tokyo_run, h5)
    return h5


def test_output_names_derive_from_the_hdf5_name():
    p = output_paths("out/run.h5")
    assert p == {"obs": "out/run.obs", "nav": "out/run.nav", "nmea": "out/run.nmea", "kml": "out/run.kml",
                 "gpx": "out/run.gpx", "report": "out/run_report.png"}


def test_output_config_keys_default_off_and_validate():
    out = load_receiver_config(None).output
    assert (out.rinex, out.nmea, out.kml, out.gpx, out.report) == (False, False, False, False, False)
    assert export_all("does-not-matter.h5", out) == {}          # nothing enabled: the file is not opened
    with pytest.raises(UserError, match="output.kml"):
        load_receiver_config(None, [("output.kml", "yes")])


@pytest.mark.slow
def test_export_command_writes_the_requested_files_only(linked):
    res = CliRunner().invoke(main, ["export", str(linked), "--kml", "--gpx"])
    assert res.exit_code == 0, res.output
    d = linked.parent
    assert (d / "run.kml").exists() and (d / "run.gpx").exists()
    assert not (d / "run.obs").exists() and not (d / "run.nmea").exists()
    assert "wrote" in res.output and "run.kml" in res.output
    res = CliRunner().invoke(main, ["export", str(linked), "--all", "-q"])
    assert res.exit_code == 0 and res.output == ""
    assert all((d / f"run.{ext}").exists() for ext in ("obs", "nav", "nmea", "kml", "gpx"))


def _one_line_error(args, message):
    res = CliRunner().invoke(main, args)
    assert res.exit_code == 2
    assert message in res.output and len(res.output.strip().splitlines()) == 1


@pytest.mark.parametrize("args, message", [
    (["export", "missing.h5", "--rinex"], "run file not found: missing.h5"),
    (["info", str(ROOT / "configs" / "gpssim_static_tokyo.yaml")], "is not an HDF5 file"),
])
def test_cli_errors_are_one_line(args, message):
    _one_line_error(args, message)


@pytest.mark.parametrize("args, message", [
    (["export", "{h5}"], "nothing to export"),
    (["report", "{h5}", "--truth", "missing.yaml"], "truth file not found"),
])
def test_cli_errors_on_a_run_file_are_one_line(linked, args, message):
    _one_line_error([a.format(h5=linked) for a in args], message)


@pytest.mark.slow
def test_report_command(linked, tmp_path):
    out = tmp_path / "r.png"
    res = CliRunner().invoke(main, ["report", str(linked), "--truth", str(TOKYO_META), "-o", str(out)])
    assert res.exit_code == 0, res.output
    assert out.stat().st_size > 50_000 and f"wrote {out}" in res.output


def test_info_command(linked):
    res = CliRunner().invoke(main, ["info", str(linked)])
    assert res.exit_code == 0, res.output
    text = res.output
    for want in ("schema          gnssrx-run-2", "navigation mode assisted", "channels        10",
                 "modes         scalar", "mean position lat 35.68", "config:", "  navigation:",
                 "iono/UTC        rinex: Klobuchar alpha 1.21e-08", "  ionosphere    broadcast "):
        assert want in text, want
    res = CliRunner().invoke(main, ["info", str(linked), "--json", "--no-config"])
    assert res.exit_code == 0, res.output
    d = json.loads(res.output)
    assert "config" not in d
    import h5py
    with h5py.File(linked) as f:
        n_fix = f["navigation/gps_tow"].shape[0]
        n_obs = f["observables/prn"].shape[0]
    assert d["navigation"]["fixes"] == n_fix and d["observables"]["rows"] == n_obs
    assert d["navigation"]["iono_params"] == {"broadcast": n_fix}      # the RINEX header's set from the start
    assert d["navigation"]["rate_hz"] == pytest.approx(10.0, rel=1e-3)
    assert d["navigation"]["first_fix"]["gps_time"].startswith("2022-01-01T01:59")
    assert d["navigation"]["mean_position"]["lat_deg"] == pytest.approx(35.681298, abs=1e-4)
    assert sorted(d["channels"]) == sorted(f"G{p:02d}" for p in d["acquisition"]["detected_prns"])
    assert d["iono_utc"]["source"] == "rinex" and d["iono_utc"]["dt_ls"] == 18
    assert d["iono_utc"]["beta"][0] == pytest.approx(0.1167e6)


@pytest.mark.slow
@pytest.mark.skipif(not TOKYO_REC.exists(), reason="../shared/data reference recording absent")
def test_run_writes_enabled_outputs_beside_the_hdf5(tmp_path):
    """``gnssrx run`` calls export_all after closing the file: 2 s of the recording give channels but no
    fixes, so the report is written and the fix-based outputs are skipped with a message."""
    out = tmp_path / "short.h5"
    res = CliRunner().invoke(main, [
        "run", str(ROOT / "configs" / "gpssim_static_tokyo.yaml"), "--input", str(TOKYO_REC), "-o", str(out),
        "--set", "input.duration_s=2", "--set", "output.report=true", "--set", "output.kml=true",
        "--set", "output.rinex=true"])
    assert res.exit_code == 0, res.output
    assert out.exists() and (tmp_path / "short_report.png").exists()
    assert not (tmp_path / "short.kml").exists() and not (tmp_path / "short.obs").exists()
    assert "no KML track written" in res.output and "no RINEX observation file written" in res.output


def test_run_facts_are_run_infos_entries_from_one_opening(linked):
    """The end of a run without a fix reads only these entries (receiver.probe.hints): the same values as
    ``gnssrx info``'s, and the ephemerides are the satellites of /ephemeris."""
    import h5py
    from receiver.export.info import run_facts, run_info
    info, facts = run_info(linked), run_facts(linked)
    assert set(facts) == {"channels", "acquisition", "ephemerides"}
    for k in facts:
        assert facts[k] == info[k], k
    with h5py.File(linked) as f:
        stored = sorted({int(p) for p in f["ephemeris/prn"][:]})
    assert facts["ephemerides"] == stored and len(stored) >= 4
    assert any("mean_cn0_dbhz" in c for c in facts["channels"].values())
