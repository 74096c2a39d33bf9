"""The receiver explains itself (issue 35): did-you-mean for config keys and choices, a recording given as the
config, one rule for output directories (missing ones are made, never on bad input), bare ``gnssrx``,
help texts without source paths, the SPDX licence, the report's fix-span axes / Doppler legend / sky-plot
labels, and the no-fix explanation of a file too short for an ephemeris."""
import os
import re
import tomllib

import numpy as np
import pytest
from click.testing import CliRunner

from receiver.cli import LAZY_COMMANDS, main
from receiver.schema import load_receiver_config
from receiver.errors import UserError
from receiver.suggest import did_you_mean, looks_binary

from repo_paths import ROOT  # noqa: E402


def _one_line_error(res):
    assert res.exit_code == 2, res.output
    assert "Traceback" not in res.output and res.output.count("\n") == 1, res.output
    return res.output


def test_did_you_mean_unit():
    assert did_you_mean("pll_bw", ["pll_bw_hz", "dll_bw_hz", "pll_order"]) == " (did you mean 'pll_bw_hz'?)"
    assert did_you_mean("PLL-BW-HZ", ["pll_bw_hz"]) == " (did you mean 'pll_bw_hz'?)"
    assert did_you_mean("zzzz", ["pll_bw_hz", "dll_bw_hz"]) == ""


def test_unknown_config_key_and_choice_suggest_the_right_one():
    want = r"unknown config key 'tracking\.pll_bw' \(did you mean 'tracking\.pll_bw_hz'\?\)"
    with pytest.raises(UserError, match=want):
        load_receiver_config(None, [("tracking.pll_bw", "10")])
    with pytest.raises(UserError, match=r"got 'int8iq' \(did you mean 'int8_iq'\?\)"):
        load_receiver_config(None, [("input.format", "int8iq")])
    with pytest.raises(UserError) as e:
        load_receiver_config(None, [("navigation.nonsense_key", "1")])
    assert "did you mean" not in str(e.value)           # nothing close: no guess


def test_a_recording_given_as_config_is_named(tmp_path):
    rec = tmp_path / "rec.bin"
    np.random.default_rng(0).integers(-8, 8, 4096, dtype=np.int8).tofile(rec)
    assert looks_binary(rec.read_bytes()) and not looks_binary("input:\n  path: x.bin  # °\n".encode())
    for cmd in (["run", str(rec)], ["acquire", str(rec)]):
        out = _one_line_error(CliRunner().invoke(main, cmd))
        assert "looks like a recording (binary), not a YAML config: pass it with --input / input.path" in out
    assert sorted(os.listdir(tmp_path)) == ["rec.bin"]     # no partial output


def test_bare_gnssrx_prints_help_and_succeeds():
    res = CliRunner().invoke(main, [])
    assert res.exit_code == 0 and "Usage:" in res.output and "probe" in res.output


def test_help_texts_name_no_source_files():
    names = sorted(set(main.list_commands(None)) | set(LAZY_COMMANDS))
    for name in names:
        res = CliRunner().invoke(main, [name, "--help"])
        assert res.exit_code == 0, (name, res.output)
        assert not re.search(r"receiver/\S+|\w+\.py\b", res.output), (name, res.output)


def test_spdx_licence_string():
    meta = tomllib.loads((ROOT / "pyproject.toml").read_text())
    assert meta["project"]["license"] == "MIT"                 # SPDX expression, not the deprecated table
    assert all((ROOT / f).is_file() for f in meta["project"]["license-files"])
    req = [r for r in meta["build-system"]["requires"] if r.startswith("setuptools")]
    m = re.match(r"setuptools>=(\d+)", req[0])
    assert m and int(m.group(1)) >= 77                       # the first setuptools that reads PEP 639 strings


def test_report_makes_missing_directories_and_spans_the_fixes(tokyo_run, tmp_path):
    from receiver.export.report import make_figure
    from receiver.runfile.reader import load_run
    out = tmp_path / "new" / "deeper" / "r.png"
    res = CliRunner().invoke(main, ["report", str(tokyo_run), "-o", str(out)])
    assert res.exit_code == 0, res.output
    assert out.is_file()
    res = CliRunner().invoke(main, ["report", str(tmp_path / "missing.h5"), "-o", str(tmp_path / "n2" / "r.png")])
    assert res.exit_code == 2 and not (tmp_path / "n2").exists()      # bad input: no directory made
    run = load_run(tokyo_run)
    fig = make_figure(run)
    try:
        by = {ax.get_title(): ax for ax in fig.axes}
        t = run.fixes["time_s"]
        for title in ("position deviation from the mean position (ENU)", "velocity (ENU)"):
            lo, hi = by[title].get_xlim()
            pad = 0.05 * (t[-1] - t[0]) + 0.05
            assert t[0] - pad <= lo <= t[0] and t[-1] <= hi <= t[-1] + pad
        cn0_lo, cn0_hi = by["C/N0 per channel"].get_xlim()
        assert cn0_lo < t[0] - 1.0                              # the channel panels keep the whole file
        dop = by["carrier Doppler (NCO) per channel"].get_legend()
        assert dop is not None and {x.get_text() for x in dop.get_texts()} == \
            {f"G{int(p):02d}" for p in np.unique(run.obs["prn"])}
        sky = next(ax for ax in fig.axes if ax.get_title().startswith("sky plot"))
        fig.canvas.draw()
        r = fig.canvas.get_renderer()
        boxes = [a.get_window_extent(r) for a in sky.texts]
        assert len(boxes) == len(np.unique(run.obs["prn"]))
        for i, a in enumerate(boxes):
            for b in boxes[i + 1:]:
                assert not a.overlaps(b), (a, b)
    finally:
        import matplotlib.pyplot as plt
        plt.close(fig)


@pytest.mark.slow
def test_a_file_too_short_for_an_ephemeris_says_why_there_is_no_fix(tmp_path):
    from synth import make_signal
    from receiver.source.io import quantize
    sats = [{"prn": p, "doppler_hz": d, "code_phase_chips": c, "cn0_dbhz": 47.0}
            for p, d, c in ((5, 1200.0, 100.0), (17, -2300.0, 500.0), (28, 300.0, 900.0))]
    x = make_signal(sats, fs=2.6e6, duration_s=0.19, seed=7)
    rec = tmp_path / "short.bin"
    quantize(x, "int8_iq", 8.0).tofile(rec)
    res = CliRunner().invoke(main, ["run", str(ROOT / "configs" / "gpssim_static_tokyo.yaml"), "--input", str(rec),
                                    "-o", str(tmp_path / "short.h5"), "-q",
                                    "--set", "acquisition.high_sensitivity.enabled=false"])
    assert res.exit_code == 0, res.output
    why = [ln for ln in res.output.splitlines() if ln.startswith("why no fix")]
    assert why and "acquired 3 satellites (5 17 28)" in why[0]
    assert "too short" not in why[0] and "0.19 s" in res.output and "gnssrx snapshot" in res.output


def test_acquire_on_a_wrong_format_warns_and_says_what_to_check(tmp_path):
    from synth import make_signal
    from receiver.source.io import quantize
    x = make_signal([{"prn": 9, "doppler_hz": 500.0, "code_phase_chips": 10.0, "cn0_dbhz": 50.0}], fs=2.6e6,
                    duration_s=0.1, seed=8)
    rec = tmp_path / "r.bin"
    quantize(x, "int8_iq", 8.0).tofile(rec)
    args = ["acquire", str(ROOT / "configs" / "gpssim_static_tokyo.yaml"), "--input", str(rec),
            "--set", "acquisition.high_sensitivity.enabled=false", "--set", "acquisition.lo_search_hz=0",
            "--set", "acquisition.prns=[9, 20]"]
    res = CliRunner().invoke(main, args + ["--set", "input.format=int16_iq"])
    assert res.exit_code == 0, res.output
    assert "gnssrx: warning: input.format int16_iq does not fit the file's bytes" in res.output
    assert "no satellite found: check input.format" in res.output and f"gnssrx probe {rec}" in res.output
    res = CliRunner().invoke(main, args)                    # the right format: no warning, no hint
    assert res.exit_code == 0 and "detected: 9" in res.output, res.output
    assert "warning" not in res.output and "no satellite found" not in res.output
