"""scripts/figures/figures_index.py: figures/index.md from the figure directories and their claims.json."""
import json
import subprocess
import sys

from repo_paths import SCRIPTS
SCRIPT = SCRIPTS / "figures" / "figures_index.py"


def test_index_lists_claims_figures_and_tables(tmp_path):
    figs = tmp_path / "figures"
    leo, vec, car = figs / "leo", figs / "vector", figs / "carrier"
    for d in (leo, vec, car):
        d.mkdir(parents=True)
    for name in ("fig3_doppler.png", "fig6_rmse.png"):
        (leo / name).write_bytes(b"\x89PNG")
    (leo / "tables.md").write_text("# tables\n")
    (leo / "claims.json").write_text(json.dumps([
        {"figure": "fig6_rmse.png", "claim": "SR-CKF RMSE 136.6 m | lowest", "measured": "142.0 m",
         "status": "partly"},
        {"figure": "Table 2", "claim": "EKF 5.8 ms", "measured": "0.4 ms"},
        "not a claim"]))
    (vec / "fig_a.png").write_bytes(b"\x89PNG")
    (vec / "claims.json").write_text(json.dumps({"title": "Vector loops", "claims": [
        {"figure": "fig_a.png", "claim": "VDLL 30 % lower RMS", "measured": "27 %", "note": "5 seeds"}]}))
    (car / "claims.json").write_text("{not json")
    p = subprocess.run([sys.executable, str(SCRIPT), str(figs)], capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    text = (figs / "index.md").read_text()
    assert "## leo" in text and "## vector: Vector loops" in text and "## carrier" in text
    assert "| [fig6_rmse.png](leo/fig6_rmse.png) | SR-CKF RMSE 136.6 m \\| lowest | 142.0 m | partly |" in text
    assert "| Table 2 | EKF 5.8 ms | 0.4 ms |  |" in text
    assert "* [fig3_doppler.png](leo/fig3_doppler.png)" in text          # figure without a claim
    assert "[tables.md](leo/tables.md)" in text
    assert "| [fig_a.png](vector/fig_a.png) | VDLL 30 % lower RMS | 27 % | 5 seeds |" in text
    assert "claims.json problem" in text and "carrier" in p.stderr
    assert "1 entry of claims.json skipped" in text


def test_index_without_figures(tmp_path):
    out = tmp_path / "idx.md"
    p = subprocess.run([sys.executable, str(SCRIPT), str(tmp_path / "none"), "--out", str(out)],
                       capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    assert "no figure directories found" in out.read_text()
