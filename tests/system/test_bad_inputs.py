"""Bad inputs and faults (issue "Hardening"): every case ends with exit code 2 and one line on stderr (130 /
143 for SIGINT / SIGTERM), or -- where running on is right -- a correct result plus a warning line; never a
traceback, never an output file after a failure, and the input file is unchanged (checksum).

The recordings are simulated here (embedded constellation, no ../shared needed) and kept short.  The CLI
is driven in-process with click's CliRunner where that is faithful, and in a subprocess for what needs a
real process: the file-size limit (``resource.setrlimit(RLIMIT_FSIZE)``, the ``ulimit -f`` disk-full case)
and signals sent mid-run.  scripts/bench/signal_trials.py repeats the signal cases 20 + 20 times.
"""
import hashlib
import os
import resource
import signal
import subprocess
import sys
import time
from pathlib import Path

import h5py
import numpy as np
import pytest
import yaml

from receiver.schema import load_receiver_config

from clirun import cli
from repo_paths import ROOT
SCENARIO = ROOT / "configs" / "scenarios" / "static_default.yaml"
FS = 2.0e6


def sha(path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for blk in iter(lambda: fh.read(1 << 20), b""):
            h.update(blk)
    return h.hexdigest()


def leftovers(d, stem):
    return sorted(p.name for p in Path(d).iterdir() if p.name.startswith(stem))


def one_error_line(stderr: str, code_text: str = "gnssrx: ") -> str:
    assert "Traceback" not in stderr, stderr
    lines = [ln for ln in stderr.splitlines() if ln.strip()]
    assert len(lines) == 1, stderr
    assert lines[0].startswith(code_text), lines[0]
    return lines[0]




def subprocess_cli(args, cwd, preexec_fn=None, timeout=600):
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    return subprocess.run([sys.executable, "-m", "receiver.cli", *map(str, args)], cwd=cwd, env=env,
                          capture_output=True, text=True, preexec_fn=preexec_fn, timeout=timeout)


# ---------------------------------------------------------------------------------------- recordings
@pytest.fixture(scope="module")
def rec(tmp_path_factory):
    """3 s int8_iq recording at 2 MS/s, its receiver config (fragment) and the broadcast RINEX nav file."""
    from receiver.batch.tasks import write_nav_for_scenario
    from receiver.sim.scenario import load_scenario
    from receiver.sim.simulate import simulate
    d = tmp_path_factory.mktemp("rec")
    ov = [("time.duration_s", 3.0), ("frontend.sample_rate_hz", FS)]
    paths = simulate(SCENARIO, d / "rec.bin", ov, progress=False)
    write_nav_for_scenario(load_scenario(SCENARIO, ov).to_dict(), str(d / "rec.nav"))
    cfg = yaml.safe_load(Path(paths["yaml"]).read_text())
    cfg["input"]["path"] = str(d / "rec.bin")
    cfg["navigation"] = {"ephemeris": str(d / "rec.nav")}
    (d / "rec.yaml").write_text(yaml.safe_dump(cfg))
    return {"dir": d, "bin": d / "rec.bin", "yaml": d / "rec.yaml", "nav": d / "rec.nav",
            "truth": Path(paths["truth"]), "sha": sha(d / "rec.bin")}


def check_untouched(rec):
    assert sha(rec["bin"]) == rec["sha"]


# ---------------------------------------------------------------------------------------- 1. output
def test_output_equal_to_input_is_refused(rec, tmp_path):
    before = leftovers(rec["dir"], "rec.bin.") + leftovers(rec["dir"], "rec.yaml.")   # e.g. the simulator's .tag
    rc, out, err = cli(["run", rec["yaml"], "-o", rec["bin"]])
    assert rc == 2 and "same file as the input" in one_error_line(err)
    check_untouched(rec)
    # through a symbolic link, and the config file itself
    os.symlink(rec["bin"], tmp_path / "link.h5")
    rc, out, err = cli(["run", rec["yaml"], "-o", tmp_path / "link.h5"])
    assert rc == 2 and "same file as the input" in one_error_line(err)
    rc, out, err = cli(["run", rec["yaml"], "-o", rec["yaml"]])
    assert rc == 2 and "same file as the input" in one_error_line(err)
    check_untouched(rec)
    assert leftovers(rec["dir"], "rec.bin.") + leftovers(rec["dir"], "rec.yaml.") == before


def test_output_is_a_directory_missing_parent_name_too_long(rec, tmp_path):
    os.mkdir(tmp_path / "out.h5")
    rc, out, err = cli(["run", rec["yaml"], "-o", tmp_path / "out.h5"])
    assert rc == 2 and "is a directory" in one_error_line(err)
    (tmp_path / "afile").write_text("x")
    rc, out, err = cli(["run", rec["yaml"], "-o", tmp_path / "afile" / "sub" / "r.h5"])
    assert rc == 2 and "cannot create the output directory" in one_error_line(err)
    name = "r" * 252 + ".h5"                   # a legal 255-byte name; with ".partial" it is not
    rc, out, err = cli(["run", rec["yaml"], "-o", tmp_path / name])
    assert rc == 2 and "too long" in one_error_line(err)
    assert sorted(os.listdir(tmp_path)) == ["afile", "out.h5"]
    check_untouched(rec)


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into read-only directories")
def test_unwritable_directory(rec, tmp_path):
    d = tmp_path / "ro"
    d.mkdir()
    d.chmod(0o555)
    try:
        rc, out, err = cli(["run", rec["yaml"], "-o", d / "r.h5"])
        assert rc == 2 and "not writable" in one_error_line(err)
    finally:
        d.chmod(0o755)


def test_missing_output_directory_is_created_and_the_run_is_atomic(rec, tmp_path):
    out = tmp_path / "new" / "deeper" / "r.h5"
    rc, stdout, err = cli(["run", rec["yaml"], "-o", out, "--set", "navigation.enabled=false",
                           "--set", "input.duration_s=0.6"])
    assert rc == 0, err
    assert leftovers(out.parent, "r.h5") == ["r.h5"]              # no .partial, no .lock
    with h5py.File(out) as f:
        assert f.attrs["schema"] == "gnssrx-run-2" and f.attrs["nonfinite_samples"] == 0
        assert len(f["channels"]) >= 4
    check_untouched(rec)


def test_output_locked_by_another_run(rec, tmp_path):
    out = tmp_path / "r.h5"
    holder = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        (tmp_path / "r.h5.lock").write_text(f"{holder.pid}\n")
        rc, stdout, err = cli(["run", rec["yaml"], "-o", out])
        assert rc == 2 and f"being written by another run (pid {holder.pid}" in one_error_line(err)
        assert leftovers(tmp_path, "r.h5") == ["r.h5.lock"]      # the other run's lock is left alone
    finally:
        holder.kill()
        holder.wait()
    # the lock of a process that is gone is stale: taken over
    rc, stdout, err = cli(["run", rec["yaml"], "-o", out, "--set", "navigation.enabled=false",
                           "--set", "input.duration_s=0.6"])
    assert rc == 0, err
    assert leftovers(tmp_path, "r.h5") == ["r.h5"]


def test_standard_outputs_must_not_overwrite_an_input(rec, tmp_path):
    """output.rinex writes <stem>.nav beside the run file: rec.h5 beside rec.nav would replace the
    ephemeris file the run reads."""
    before = sha(rec["nav"])
    rc, out, err = cli(["run", rec["yaml"], "-o", rec["dir"] / "rec.h5", "--set", "output.rinex=true"])
    assert rc == 2 and "output.rinex would overwrite" in one_error_line(err)
    assert sha(rec["nav"]) == before and leftovers(rec["dir"], "rec.h5") == []


def test_disk_full_is_one_line_and_leaves_no_file(rec, tmp_path):
    """The file-size limit (ulimit -f) stands in for a full disk: HDF5 used to crash after ~1,500 lines."""
    def limit():
        resource.setrlimit(resource.RLIMIT_FSIZE, (200_000, 200_000))
    r = subprocess_cli(["run", rec["yaml"], "-o", tmp_path / "r.h5", "-q"], tmp_path, preexec_fn=limit)
    assert r.returncode == 2, r.stderr[-2000:]
    line = one_error_line(r.stderr)
    assert "writing the output" in line and "File too large" in line
    assert os.listdir(tmp_path) == []
    check_untouched(rec)


def test_simulate_disk_full(tmp_path):
    def limit():
        resource.setrlimit(resource.RLIMIT_FSIZE, (300_000, 300_000))
    r = subprocess_cli(["simulate", SCENARIO, "-o", tmp_path / "s.bin", "-q", "--set", "time.duration_s=0.5",
                        "--set", f"frontend.sample_rate_hz={FS}"], tmp_path, preexec_fn=limit)
    assert r.returncode == 2 and "disk full or file size limit" in one_error_line(r.stderr)
    assert os.listdir(tmp_path) == []


def test_simulate_refuses_to_overwrite_its_scenario(tmp_path):
    sc = tmp_path / "sc.yaml"
    sc.write_text(SCENARIO.read_text())
    before = sha(sc)
    rc, out, err = cli(["simulate", sc, "-o", tmp_path / "sc.bin", "-q"])   # would write sc.yaml
    assert rc == 2 and "same file as the input" in one_error_line(err)
    assert sha(sc) == before and sorted(os.listdir(tmp_path)) == ["sc.yaml"]


# ---------------------------------------------------------------------------------------- 2. signals
def _signal_run(args, cwd, watch: Path, sig, delay_s: float, timeout=600):
    """Start the CLI, wait until `watch` (a temporary file) exists, wait delay_s, send sig."""
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    p = subprocess.Popen([sys.executable, "-m", "receiver.cli", *map(str, args)], cwd=cwd, env=env,
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    t0 = time.monotonic()
    while not watch.exists() and p.poll() is None and time.monotonic() - t0 < timeout:
        time.sleep(0.02)
    time.sleep(delay_s)
    sent = p.poll() is None
    if sent:
        p.send_signal(sig)
    out, err = p.communicate(timeout=timeout)
    return sent, p.returncode, out, err


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_signal_during_run(rec, tmp_path, sig):
    out = tmp_path / "r.h5"
    sent, rc, stdout, err = _signal_run(["run", rec["yaml"], "-o", out], tmp_path,
                                        tmp_path / "r.h5.partial", sig, 0.3)
    assert sent, "the run finished before the signal"
    assert rc == 128 + sig
    assert f"interrupted by {signal.Signals(sig).name}" in one_error_line(err)
    assert os.listdir(tmp_path) == []                    # no final file, no .partial, no .lock
    check_untouched(rec)


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_signal_during_simulate(tmp_path, sig):
    sent, rc, stdout, err = _signal_run(
        ["simulate", SCENARIO, "-o", tmp_path / "s.bin", "-q", "--set", "time.duration_s=20",
         "--set", f"frontend.sample_rate_hz={FS}"], tmp_path, tmp_path / "s.bin.partial", sig, 0.5)
    assert sent
    assert rc == 128 + sig
    assert f"interrupted by {signal.Signals(sig).name}" in one_error_line(err)
    assert os.listdir(tmp_path) == []                    # neither recording nor truth, final or partial


# ---------------------------------------------------------------------------------------- 3. input
@pytest.mark.parametrize("kind", ["zeros", "constant"])
def test_all_zero_and_constant_inputs_find_nothing(rec, tmp_path, kind):
    x = np.zeros(2 * int(1.0 * FS), np.int8)
    if kind == "constant":
        x[0::2], x[1::2] = 23, -9                  # DC only
    x.tofile(tmp_path / "in.bin")
    rc, out, err = cli(["run", rec["yaml"], "--input", tmp_path / "in.bin", "-o", tmp_path / "r.h5"])
    assert rc == 0, err
    assert "tracked         0 satellites" in out and "fixes           none" in out
    with h5py.File(tmp_path / "r.h5") as f:
        assert not f["acquisition/detected"][:].any() and len(f["channels"]) == 0
    rc, out, err = cli(["acquire", rec["yaml"], "--input", tmp_path / "in.bin"])
    assert rc == 0 and "\ndetected: none" in out and "Traceback" not in err


def test_search_on_zero_power_returns_no_detection():
    from receiver.acquisition import search
    res = search(np.zeros(int(0.2 * FS), np.complex64), 0, FS, 0.0, [1, 2, 3])
    assert [r.detected for r in res] == [False] * 3 and all(np.isfinite(r.cn0_dbhz_est) for r in res)


@pytest.fixture(scope="module")
def nan_runs(tmp_path_factory):
    """A 6 s complex64 recording with and without a burst of 200 NaN samples at 3 s, both run assisted."""
    from receiver.batch.tasks import write_nav_for_scenario
    from receiver.pipeline import run
    from receiver.sim.scenario import load_scenario
    from receiver.sim.simulate import simulate
    d = tmp_path_factory.mktemp("nan")
    ov = [("time.duration_s", 6.0), ("frontend.format", "complex64"), ("frontend.sample_rate_hz", FS)]
    paths = simulate(SCENARIO, d / "clean.bin", ov, progress=False)
    write_nav_for_scenario(load_scenario(SCENARIO, ov).to_dict(), str(d / "e.nav"))
    raw = np.fromfile(paths["if"], np.complex64)
    i = int(3.0 * FS)
    raw[i:i + 200] = np.nan
    raw.tofile(d / "burst.bin")
    del raw
    out = {}
    for name in ("clean", "burst"):
        cfg = load_receiver_config(paths["yaml"], [("input.path", str(d / f"{name}.bin")),
                                                   ("output.path", str(d / f"{name}.h5")),
                                                   ("navigation.ephemeris", str(d / "e.nav"))])
        out[name] = run(cfg, quiet=True)
    out["dir"], out["truth"] = d, paths["truth"]
    return out


def test_nan_burst_keeps_the_fixes(nan_runs):
    """200 NaN samples (100 us) in a complex64 file used to drop every channel for good."""
    clean, burst = nan_runs["clean"], nan_runs["burst"]
    print(f"\nfixes: clean {clean.n_fixes}, NaN burst {burst.n_fixes}; tracked {clean.tracked} / "
          f"{burst.tracked}")
    assert clean.n_fixes >= 30
    assert burst.n_fixes >= 0.9 * clean.n_fixes
    assert burst.tracked == clean.tracked
    assert burst.nonfinite_samples == 200 and clean.nonfinite_samples == 0
    assert "200 non-finite samples replaced by zeros" in burst.text()
    assert "non-finite" not in clean.text()
    with h5py.File(nan_runs["dir"] / "burst.h5") as f:
        assert f.attrs["nonfinite_samples"] == 200
        # channels keep their lock after the burst
        for g in f["channels"].values():
            t, lock = g["time_s"][:], g["pll_lock"][:]
            assert lock[(t > 3.5)].mean() > 0.9


def test_reader_counts_each_nonfinite_sample_once(tmp_path):
    from receiver.source.io import SampleReader
    x = np.ones(10_000, np.complex64)
    x[100:110] = np.nan
    x[5000] = np.inf + 0j
    x[9000] = complex(1.0, np.nan)
    x.tofile(tmp_path / "x.bin")
    r = SampleReader(tmp_path / "x.bin", "complex64", 1e6)
    total = 0
    for start in range(0, 10_000, 1000):               # overlapping reads, as the pipeline's chunks
        b = r.read(start, 1300)
        assert np.all(np.isfinite(b))
        total += np.count_nonzero(b == 0)
    assert r.n_nonfinite == 12 and r.first_nonfinite == 100
    assert total > 12                                  # the overlap re-reads zeros, counted once


def test_nonfinite_cn0_estimate_resets_instead_of_dropping_the_channel():
    from receiver.tracking import kernel as K
    from receiver.tracking.scalar import Channel
    from synth import make_signal
    fs = 2.6e6
    x = make_signal([dict(prn=21, doppler_hz=500.0, code_phase_chips=5.0, cn0_dbhz=45.0)], fs, 4.0, seed=7)
    ch = Channel(21, 500.0, 5.0, 0, load_receiver_config(None, []).tracking, fs, 0.0)
    recs, chunk = [], int(0.5 * fs)
    for start in range(0, len(x), chunk):
        if start == 4 * chunk:                         # the estimator and lock filters go non-finite
            ch.st[K.S_CN0], ch.st[K.S_ACC_M2], ch.st[K.S_LOCK_ABSI] = np.nan, np.inf, np.nan
        s = ch.next_sample
        recs.append(ch.process(x[s:start + chunk + int(0.03 * fs)], s))
    r = np.concatenate(recs)
    assert not ch.lost
    late = r[r["time_s"] > 3.0]
    assert late["pll_lock"].mean() > 0.95
    assert np.median(late["cn0_dbhz"]) == pytest.approx(45.0, abs=1.0)


# ---------------------------------------------------------------------------------------- 4. meaning
@pytest.mark.parametrize("sets,match", [
    (["input.if_hz=1.2e6"], "'input.if_hz' must be within +/- sample_rate_hz/2"),
    (["input.if_hz=-1.0e6"], "'input.if_hz' must be within +/- sample_rate_hz/2"),
    (["input.format=int8_real", "input.if_hz=0"], "must be in (0, sample_rate_hz/2"),
    (["input.format=int8_real", "input.if_hz=1.5e6"], "must be in (0, sample_rate_hz/2"),
    (["acquisition.prns=[]"], "'acquisition.prns' is empty"),
])
def test_meaningless_values(rec, tmp_path, sets, match):
    args = ["run", rec["yaml"], "-o", tmp_path / "r.h5"]
    for s in sets:
        args += ["--set", s]
    rc, out, err = cli(args)
    assert rc == 2 and match in one_error_line(err)
    assert os.listdir(tmp_path) == []


def test_if_inside_the_band_is_accepted():
    cfg = load_receiver_config(None, ["input.format=int16_real", "input.if_hz=650e3",
                                      "input.sample_rate_hz=2.6e6"])
    assert cfg.input.if_hz == 650e3
    assert load_receiver_config(None, ["input.if_hz=-1.29e6"]).input.if_hz == -1.29e6


def test_duplicate_prns_are_searched_once():
    import logging
    records = []
    h = logging.Handler()
    h.emit = records.append
    lg = logging.getLogger("receiver.warnings")
    lg.addHandler(h)
    try:
        cfg = load_receiver_config(None, ["acquisition.prns=[3, 5, 3, 7, 5]"])
    finally:
        lg.removeHandler(h)
    assert cfg.acquisition.prns == [3, 5, 7]
    assert [r.getMessage() for r in records] == ["acquisition.prns lists PRN 3, 5 more than once; each is "
                                                 "searched once"]


def test_rinex_without_usable_records(rec, tmp_path):
    text = rec["nav"].read_text()
    head, body = text.split("END OF HEADER", 1)
    header = head + "END OF HEADER\n"
    (tmp_path / "empty.nav").write_text(header)
    # a version-2 body (PRN in columns 1-2, two-digit year, 3-space indent) under the version-3 header
    v2 = "12 22  1  1  2  0  0.0" + " 0.100000000000D-03" * 3 + "\n"
    v2 += ("   " + " 0.100000000000D+01" * 4 + "\n") * 7
    (tmp_path / "v2body.nav").write_text(header + v2)
    for name in ("empty.nav", "v2body.nav"):
        rc, out, err = cli(["run", rec["yaml"], "-o", tmp_path / "r.h5", "--set",
                            f"navigation.ephemeris={tmp_path / name}"])
        assert rc == 2 and "no usable GPS navigation records" in one_error_line(err)
    assert not (tmp_path / "r.h5").exists() and not (tmp_path / "r.h5.partial").exists()


def test_vector_start_after_the_end_warns(rec, tmp_path):
    rc, out, err = cli(["run", rec["yaml"], "-o", tmp_path / "r.h5", "--set", "vector.enabled=true",
                        "--set", "vector.start_s=100", "--set", "input.duration_s=1.0"])
    assert rc == 0
    assert "Traceback" not in err
    warn = [ln for ln in err.splitlines() if "warning" in ln]
    assert len(warn) == 1 and "vector.start_s=100 s is after the end of the processed span" in warn[0]
    with h5py.File(tmp_path / "r.h5") as f:
        assert "vector" not in f


def test_eval_without_time_overlap(nan_runs, tmp_path):
    from receiver.sim.simulate import simulate
    other = simulate(SCENARIO, tmp_path / "o.bin", [("time.duration_s", 0.05), ("time.tow_s", 100000.0),
                                                    ("frontend.sample_rate_hz", 1.0e6)], progress=False)
    rc, out, err = cli(["eval", nan_runs["dir"] / "clean.h5", other["truth"]])
    assert rc == 2 and "do not overlap the truth file's span" in one_error_line(err)
    rc, out, err = cli(["eval", nan_runs["dir"] / "clean.h5", nan_runs["truth"]])
    assert rc == 0 and "fixes (scored / total)" in out


# ---------------------------------------------------------------------------------------- 5. text
LATIN1 = "# Genève, 46°N\n".encode("latin-1")


def test_non_utf8_config(rec, tmp_path):
    p = tmp_path / "c.yaml"
    p.write_bytes(LATIN1 + rec["yaml"].read_bytes())
    rc, out, err = cli(["run", p, "-o", tmp_path / "r.h5"])
    line = one_error_line(err)
    assert rc == 2 and "is not UTF-8 text (byte 0xe8 on line 1)" in line


def test_non_utf8_scenario_batch_and_trajectory(tmp_path):
    sc = tmp_path / "sc.yaml"
    sc.write_bytes(LATIN1 + b"time: {duration_s: 0.05}\n")
    rc, out, err = cli(["simulate", sc, "-o", tmp_path / "s.bin", "-q"])
    assert rc == 2 and "is not UTF-8 text" in one_error_line(err)
    b = tmp_path / "b.yaml"
    b.write_bytes(LATIN1 + b"runs: []\n")
    rc, out, err = cli(["batch", b, "--dry-run"])
    assert rc == 2 and "is not UTF-8 text" in one_error_line(err)
    csv = tmp_path / "t.csv"
    csv.write_bytes(LATIN1 + b"0,4331297.0,567555.6,4633133.0\n10,4331297.0,567555.6,4633133.0\n")
    sc.write_text(yaml.safe_dump({"time": {"duration_s": 0.05}, "frontend": {"sample_rate_hz": 1.0e6},
                                  "receiver": {"trajectory": "csv", "csv": {"path": str(csv)}}}))
    rc, out, err = cli(["simulate", sc, "-o", tmp_path / "s.bin", "-q"])
    assert rc == 2 and "trajectory CSV" in one_error_line(err) and "not UTF-8" in err
    assert sorted(os.listdir(tmp_path)) == ["b.yaml", "sc.yaml", "t.csv"]


# ---------------------------------------------------------------------------------------- 5. run/truth files
def _replace(f, name, data):
    del f[name]
    f[name] = data


@pytest.mark.parametrize("damage,named", [
    (lambda f: _replace(f, "navigation/gps_tow", np.array([b"monday"] * len(f["navigation/gps_tow"]))),
     "/navigation/gps_tow has type |S6, expected numbers"),
    (lambda f: _replace(f, "navigation/ecef", f["navigation/ecef"][:, 0]), "/navigation/ecef has shape"),
    (lambda f: _replace(f, "navigation/n_sats", f["navigation/n_sats"][:-3]), "/navigation/n_sats has"),
    (lambda f: _replace(f, "observables/prn", np.zeros((len(f["observables/prn"]), 2))),
     "/observables/prn has shape"),
    (lambda f: f.attrs.__setitem__("sample_rate_hz", "fast"), "attribute /sample_rate_hz is 'fast'"),
])
def test_run_file_with_wrong_dataset_types(nan_runs, tmp_path, damage, named):
    """info / export / report / eval on a damaged run file: one line naming the dataset, exit code 2."""
    p = tmp_path / "bad.h5"
    p.write_bytes((nan_runs["dir"] / "clean.h5").read_bytes())
    with h5py.File(p, "a") as f:
        damage(f)
    before = sha(p)
    for args in (["info", p], ["export", p, "--nmea", "--kml"], ["report", p, "-o", tmp_path / "r.png"],
                 ["eval", p, nan_runs["truth"]]):
        rc, out, err = cli(args)
        line = one_error_line(err)
        assert rc == 2 and named in line and str(p) in line, (args, line)
    assert sha(p) == before and sorted(os.listdir(tmp_path)) == ["bad.h5"]


def test_report_must_not_overwrite_the_run_file(nan_runs, tmp_path):
    p = tmp_path / "run.h5"
    p.write_bytes((nan_runs["dir"] / "clean.h5").read_bytes())
    before = sha(p)
    rc, out, err = cli(["report", p, "-o", p])
    assert rc == 2 and "same file as the input" in one_error_line(err)
    assert sha(p) == before


def test_truth_file_with_wrong_dataset_types(nan_runs, tmp_path):
    p = tmp_path / "truth.h5"
    p.write_bytes(Path(nan_runs["truth"]).read_bytes())
    with h5py.File(p, "a") as f:
        _replace(f, "receiver/ecef", np.array(["here"] * len(f["receiver/ecef"])).astype("S"))
    rc, out, err = cli(["eval", nan_runs["dir"] / "clean.h5", p])
    assert rc == 2 and "/receiver/ecef has type" in one_error_line(err)
    rc, out, err = cli(["report", nan_runs["dir"] / "clean.h5", "--truth", p, "-o", tmp_path / "r.png"])
    assert rc == 2 and "/receiver/ecef has type" in one_error_line(err)
    assert not (tmp_path / "r.png").exists()
