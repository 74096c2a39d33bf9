"""A file that ends just after a chunk start, inside the previous chunk's overlap (GPS-SDR-SIM with an
oscillator error: 60 s + 179 samples at 3 MS/s).
The previous block already reached the end of the file; a channel whose next epoch did not fit
stopped before the last chunk's start.  Before: the pipeline ran that chunk and the kernel raised
'channel is behind the block start' (the whole run lost); now the run ends with the previous chunk and the
navigation epochs up to the end of the file are formed."""
from pathlib import Path

import h5py
import pytest
import yaml

from receiver.schema import load_receiver_config
from receiver.pipeline import CHUNK_S, run
from receiver.sim.simulate import simulate

from repo_paths import ROOT
SCENARIO = ROOT / "configs" / "scenarios" / "static_default.yaml"
FS = 2.0e6


@pytest.mark.slow
def test_run_completes_when_the_file_ends_inside_the_overlap(tmp_path):
    dur = 6 * CHUNK_S + 1e-4                       # ends 0.1 ms after a chunk start (the acquisition at 0)
    paths = simulate(str(SCENARIO), str(tmp_path / "r.bin"),
                     [("time.duration_s", dur), ("frontend.sample_rate_hz", FS)], progress=False)
    cfg = yaml.safe_load(Path(paths["yaml"]).read_text())
    cfg["input"]["path"] = str(tmp_path / "r.bin")
    (tmp_path / "r.yaml").write_text(yaml.safe_dump(cfg))
    out = tmp_path / "r.h5"
    run(load_receiver_config(str(tmp_path / "r.yaml"), [("output.path", str(out))]), quiet=True)
    with h5py.File(out, "r") as f:
        names = list(f["channels"])
        assert len(names) >= 4
        for n in names:
            s = f["channels"][n]["sample_index"][:]
            assert len(s) > 1000                                  # tracked to the end
            assert s[-1] / FS > dur - 0.05
