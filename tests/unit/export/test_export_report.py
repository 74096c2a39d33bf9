"""PNG run report (receiver.export.report)."""
import h5py
import numpy as np
import pytest

from receiver.export.report import make_figure, read_channels, summary_stats, write_report
from receiver.runfile.reader import load_run
from receiver.runfile.truth import load_truth

from repo_paths import TOKYO_META

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def _png_size(path):
    with open(path, "rb") as fh:
        head = fh.read(24)
    assert head[:8] == PNG_MAGIC
    return int.from_bytes(head[16:20], "big"), int.from_bytes(head[20:24], "big")


def test_report_of_the_reference_run_with_truth(tokyo_exports):
    path = tokyo_exports["report"]
    assert path.endswith("tokyo_report.png")
    assert _png_size(path) == (1700, 2100)
    run = load_run(tokyo_exports["h5"])
    s = summary_stats(run, load_truth(TOKYO_META))
    assert s["n_fixes"] == len(run.fixes) and s["truth_n"] == len(run.fixes)
    first = run.attrs["first_sample"] / run.attrs["sample_rate_hz"]
    assert s["ttff_s"] == pytest.approx(run.fixes["time_s"][0] - first) and 0.0 < s["ttff_s"] < 40.0
    assert s["err_3d_rms_m"] < 5.0                         # GPS-SDR-SIM without troposphere, Klobuchar on
    assert s["vel_3d_rms_mps"] < 0.5


@pytest.mark.slow
def test_figure_panels_and_vector_mode_shading(tokyo_run, tmp_path):
    run = load_run(tokyo_run)
    run.fixes["mode"][len(run.fixes) // 2:] = 1            # pretend the second half ran in vector mode
    channels = read_channels(tokyo_run)
    assert set(channels) == {int(p) for p in run.obs["prn"]}
    assert all(len(c["time_s"]) <= 3000 for c in channels.values())
    fig = make_figure(run, truth=load_truth(TOKYO_META), channels=channels)
    try:
        titles = [ax.get_title() for ax in fig.axes]
        for want in ("C/N0 per channel", "carrier Doppler (NCO) per channel", "lock status per channel",
                     "position error vs truth (ENU)", "velocity error vs truth (ENU)", "satellites and DOP",
                     "receiver clock"):
            assert want in titles, want
        assert any(t.startswith("sky plot") for t in titles)
        pos_ax = fig.axes[titles.index("position error vs truth (ENU)")]
        labels = [h.get_label() for h in pos_ax.get_legend().legend_handles]
        assert "vector mode" in labels
        spans = [p for p in pos_ax.patches if p.get_label() == "vector mode"]
        assert len(spans) == 1
        sp = spans[0]
        x = (np.array([sp.get_x(), sp.get_x() + sp.get_width()]) if hasattr(sp, "get_width")
             else np.asarray(sp.get_xy())[:, 0])
        t = run.fixes["time_s"]
        assert x.min() == pytest.approx(t[len(t) // 2]) and x.max() == pytest.approx(t[-1])
    finally:
        import matplotlib.pyplot as plt
        plt.close(fig)
    out = tmp_path / "vec.png"
    write_report(run, out)                                  # without truth
    assert _png_size(out) == (1700, 2100)


def test_channel_reduction_keeps_gaps_and_lock_states(tmp_path):
    """read_channels on a synthetic channel: 1 ms records, lost at 1.3 s, re-acquired at 20.5 s."""
    t = np.concatenate([np.arange(0, 1.3, 0.001), np.arange(20.5, 30.0, 0.001)])
    state = np.where(t < 0.3, 0, 2).astype(np.uint8)
    state[np.argmax(t > 1.29)] = 3                           # lost just before the gap
    state[(t >= 20.5) & (t < 20.8)] = 0                      # pull-in after re-acquisition
    lock = (state == 2).astype(np.uint8)
    cn0 = np.where(state == 2, 40.0, 30.0).astype(np.float32)
    with h5py.File(tmp_path / "c.h5", "w") as f:
        g = f.create_group("channels/G07")
        g.attrs["prn"] = 7
        for name, v in (("time_s", t), ("state", state), ("pll_lock", lock), ("cn0_dbhz", cn0),
                        ("doppler_hz", np.full(len(t), 1234.5))):
            g.create_dataset(name, data=v)
    ch = read_channels(tmp_path / "c.h5", max_points=500)[7]
    assert len(ch["time_s"]) <= 500
    assert ch["gap"].sum() == 1 and ch["time_s"][ch["gap"]][0] == pytest.approx(20.5)
    assert ch["t_end"][np.nonzero(ch["gap"])[0][0] - 1] < 1.3
    assert np.any(ch["state"] == 3) and np.all(ch["state"][ch["time_s"] > 21.0] == 2)
    assert np.allclose(ch["doppler"], 1234.5)
    assert np.all(ch["unlocked"][ch["time_s"] > 21.0] == 0.0)


@pytest.mark.slow
def test_report_of_a_run_without_fixes(tokyo_run, tmp_path):
    run = load_run(tokyo_run)
    run.fixes, run.obs = run.fixes[:0], run.obs[:0]
    out = tmp_path / "nofix.png"
    write_report(run, out)
    assert _png_size(out) == (1700, 2100)


@pytest.mark.slow
def test_vector_panels_from_the_vector_log(tokyo_run, tmp_path):
    """A run with /vector gets a sixth row: each channel's carrier R and the filter sigmas."""
    import shutil

    import h5py
    from receiver.runfile.record import VECTOR_LOG_DTYPE
    path = tmp_path / "vec.h5"
    shutil.copy(tokyo_run, path)
    run = load_run(path)
    prns = sorted({int(p) for p in run.obs["prn"]})
    n = 400
    rows = np.zeros(n, VECTOR_LOG_DTYPE)
    rows["time_s"] = np.linspace(36.0, 43.9, n)
    rows["r_code_m2"] = rows["r_carrier_m2s2"] = np.nan
    for i, p in enumerate(prns):
        rows["r_carrier_m2s2"][:, p - 1] = 300.0 * (1 + i)
    rows["sigma_pos_m"], rows["sigma_vel_mps"] = 1.0, 0.5
    with h5py.File(path, "a") as f:
        g = f.create_group("vector")
        for name in VECTOR_LOG_DTYPE.names:
            g.create_dataset(name, data=rows[name])
    fig = make_figure(load_run(path))
    try:
        titles = [ax.get_title() for ax in fig.axes]
        rax = fig.axes[[t.startswith("vector loop: carrier-discriminator R") for t in titles].index(True)]
        assert len(rax.get_lines()) == len(prns) and rax.get_yscale() == "log"
        assert "vector filter standard deviation" in titles
    finally:
        import matplotlib.pyplot as plt
        plt.close(fig)
    out = tmp_path / "vec.png"
    write_report(load_run(path), out)
    assert _png_size(out) == (1700, 2520)
