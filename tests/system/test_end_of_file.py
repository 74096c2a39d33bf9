"""End of the input (issue 31): a file that ends just past a tracking-chunk boundary."""
import numpy as np
import pytest

from receiver.schema import load_receiver_config

from synth import make_signal


@pytest.mark.slow
@pytest.mark.parametrize("extra", [117, 1500])
def test_file_ending_just_past_a_chunk_boundary(tmp_path, extra):
    """A file 1.0 s + a few samples long (the tracking chunks are 0.5 s): the channels have been offered
    its end in the second chunk and lag the third chunk's start -- before, 'channel is behind the block
    start' (a traceback) at the end of a 60-s GPS-SDR-SIM recording of 122 880 117 samples."""
    from receiver.pipeline import run
    fs = 2.048e6
    sats = [dict(prn=p, doppler_hz=d, code_phase_chips=c, cn0_dbhz=45.0)
            for p, d, c in ((3, 1200.0, 100.3), (8, -2500.0, 611.0), (19, 400.0, 901.7))]
    x = make_signal(sats, fs, (2048000 + extra) / fs, seed=2, noise_sigma=8.0)
    path = tmp_path / "eof.bin"
    q = np.empty(2 * x.size, np.int8)
    q[0::2] = np.clip(np.rint(x.real), -127, 127)
    q[1::2] = np.clip(np.rint(x.imag), -127, 127)
    q.tofile(path)
    cfg = load_receiver_config(None, [("input.path", str(path)), ("input.format", "int8_iq"),
                                      ("input.sample_rate_hz", fs), ("output.path", str(tmp_path / "eof.h5"))])
    s = run(cfg, quiet=True)
    assert s.tracked == [3, 8, 19]
