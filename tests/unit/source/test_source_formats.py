"""Input formats: fixed byte vectors for every packed format / bit order / encoding, offset binary,
header bytes, aliases, streaming writer = one-shot writer, and the simulator writing a packed format the
receiver acquires."""

import numpy as np
import pytest

from receiver.errors import UserError
from receiver.source.io import (ALIASES, FORMATS, Encoder, SampleReader, SampleWriter, bytes_per_sample,
                                quantize, resolve_format)

from repo_paths import ROOT

# byte 0b00_01_10_11 = 0x1B and 0b11_10_01_00 = 0xE4; 4-bit: 0x1B = nibbles 0001, 1011
# 2-bit codes: sign-magnitude 00 +1, 01 +3, 10 -1, 11 -3; two's complement 00 +1, 01 +3, 10 -3, 11 -1
# 4-bit codes: sign-magnitude 0001 +3, 1011 -7; two's complement 0001 +3, 1011 (-5) -9
VECTORS = [
    # gps-sdr-sim -b 1: I0 Q0 I1 Q1 ... sign bits, MSB first, 1 = positive (offset binary)
    ("packed1_iq", "msb_first", "offset_binary", [0b10011100], [1 - 1j, -1 + 1j, 1 + 1j, -1 - 1j]),
    ("packed1_iq", "lsb_first", "sign_magnitude", [0b10011100], [1 + 1j, -1 - 1j, -1 + 1j, 1 - 1j]),
    ("packed1_real", "msb_first", "twos_complement", [0x0F], [1, 1, 1, 1, -1, -1, -1, -1]),
    ("packed2_real", "msb_first", "offset_binary", [0x1B], [-3, -1, 1, 3]),
    ("packed4_iq", "lsb_first", "offset_binary", [0x0F], [15 - 15j]),
    # format, bit order, encoding, bytes, expected samples
    ("packed2_real", "msb_first", "sign_magnitude", [0x1B, 0xE4], [1, 3, -1, -3, -3, -1, 3, 1]),
    ("packed2_real", "lsb_first", "sign_magnitude", [0x1B, 0xE4], [-3, -1, 3, 1, 1, 3, -1, -3]),
    ("packed2_real", "msb_first", "twos_complement", [0x1B, 0xE4], [1, 3, -3, -1, -1, -3, 3, 1]),
    ("packed2_real", "lsb_first", "twos_complement", [0x1B, 0xE4], [-1, -3, 3, 1, 1, 3, -3, -1]),
    ("packed2_iq", "msb_first", "sign_magnitude", [0x1B], [1 + 3j, -1 - 3j]),
    ("packed2_iq", "lsb_first", "sign_magnitude", [0x1B], [-3 - 1j, 3 + 1j]),
    ("packed2_iq", "msb_first", "twos_complement", [0x1B], [1 + 3j, -3 - 1j]),
    ("packed2_iq", "lsb_first", "twos_complement", [0x1B], [-1 - 3j, 3 + 1j]),
    ("packed4_real", "msb_first", "sign_magnitude", [0x1B, 0x80], [3, -7, -1, 1]),
    ("packed4_real", "lsb_first", "sign_magnitude", [0x1B, 0x80], [-7, 3, 1, -1]),
    ("packed4_real", "msb_first", "twos_complement", [0x1B, 0x7F], [3, -9, 15, -1]),
    ("packed4_real", "lsb_first", "twos_complement", [0x1B, 0x7F], [-9, 3, -1, 15]),
    ("packed4_iq", "msb_first", "sign_magnitude", [0x1B, 0xF7], [3 - 7j, -15 + 15j]),
    ("packed4_iq", "lsb_first", "sign_magnitude", [0x1B, 0xF7], [-7 + 3j, 15 - 15j]),
    ("packed4_iq", "msb_first", "twos_complement", [0x1B, 0x87], [3 - 9j, -15 + 15j]),
    ("packed4_iq", "lsb_first", "twos_complement", [0x1B, 0x87], [-9 + 3j, 15 - 15j]),
    ("int4_iq", "msb_first", "sign_magnitude", [0x1B, 0x87, 0x70], [1 - 5j, -8 + 7j, 7 + 0j]),
    ("uint8_iq", "msb_first", "sign_magnitude", [0, 255, 127, 128], [-127.5 + 127.5j, -0.5 + 0.5j]),
]


@pytest.mark.slow
@pytest.mark.parametrize("fmt,order,enc,data,expect", VECTORS)
def test_fixed_byte_vectors(tmp_path, fmt, order, enc, data, expect):
    p = tmp_path / "v.bin"
    p.write_bytes(bytes([0xAA, 0x55, 0x00]) + bytes(data))          # 3 header bytes
    r = SampleReader(p, fmt, 1e6, header_bytes=3, bit_order=order, encoding=enc)
    assert r.n_samples == len(expect)
    y = r.read(0, len(expect))
    np.testing.assert_array_equal(y, np.array(expect, np.complex64))
    for k in range(1, len(expect)):                                 # unaligned starts
        np.testing.assert_array_equal(r.read(k, len(expect)), y[k:])
    # the writer produces the same bytes from the decoded levels
    assert quantize(y, fmt, bit_order=order, encoding=enc).tobytes() == bytes(data)


@pytest.mark.parametrize("fmt", sorted(FORMATS))
@pytest.mark.parametrize("order,enc", [("msb_first", "sign_magnitude"), ("lsb_first", "twos_complement"),
                                       ("msb_first", "offset_binary")])
def test_streaming_writer_round_trip(tmp_path, fmt, order, enc):
    """Blocks of odd sizes through the writer: the file equals the one-shot quantisation (padded), and
    the reader returns the nearest level of every sample."""
    f = FORMATS[fmt]
    rng = np.random.default_rng(2)
    n = 1001
    x = (rng.normal(size=n) + 1j * rng.normal(size=n)) * (3.0 if f.kind == "packed" else 20.0)
    p = tmp_path / "w.bin"
    with SampleWriter(p, fmt, bit_order=order, encoding=enc) as w:
        for a, b in ((0, 7), (7, 500), (500, 1001)):
            w.write(x[a:b])
    r = SampleReader(p, fmt, 1e6, bit_order=order, encoding=enc)
    assert r.n_samples >= n and p.stat().st_size == int(np.ceil(n * bytes_per_sample(fmt)))
    y = r.read(0, n).astype(np.complex128)
    comps = [x.real, x.imag] if f.complex else [x.real]
    got = [y.real, y.imag] if f.complex else [y.real]
    for c, g in zip(comps, got):
        if f.kind == "packed" and not f.integer:                    # nearest odd level, saturating
            top = 2 ** f.bits - 1
            want = np.clip(2 * np.floor(c / 2) + 1, -top, top)
        elif f.kind == "float":
            want = c.astype(np.float32)
        elif f.kind == "uint":
            want = np.clip(np.rint(c + 127.5), 0, 255) - 127.5
        else:
            lo, hi = {4: (-8, 7), 8: (-128, 127), 16: (-32768, 32767)}[f.bits or 8 * np.dtype(f.dtype).itemsize]
            want = np.clip(np.rint(c), lo, hi)
        np.testing.assert_allclose(g, want, atol=1e-5)
    if not f.complex:
        assert np.all(y.imag == 0)


def test_aliases_and_errors(tmp_path):
    assert resolve_format("ibyte").name == "int8_iq" and resolve_format("gr_complex").name == "complex64"
    assert resolve_format("cu8").name == "uint8_iq" and resolve_format("ci16_le").name == "int16_iq"
    assert all(a in FORMATS for a in ALIASES.values())
    p = tmp_path / "a.bin"
    p.write_bytes(bytes(range(8)))
    r = SampleReader(p, "cbyte", 1e6)
    assert r.read(0, 1)[0] == 0 + 1j
    with pytest.raises(UserError, match="header_bytes"):
        SampleReader(p, "int8_iq", 1e6, header_bytes=8)
    with pytest.raises(UserError, match="bit order"):
        SampleReader(p, "packed2_real", 1e6, bit_order="middle")
    with pytest.raises(UserError, match="encoding"):
        Encoder("packed2_iq", encoding="gray")
    with pytest.raises(UserError, match="unknown input format"):
        SampleReader(p, "sc12", 1e6)


@pytest.mark.slow
def test_simulated_packed2_real_if_is_acquired(tmp_path):
    """A 2-bit real-IF recording (MAX2769-like: 4.092 MHz IF at 16.368 MS/s, LSB-first two's complement)
    written by the simulator: the receiver's reader and acquisition find every simulated PRN at the true
    Doppler."""
    import h5py
    from receiver.acquisition import search
    from receiver.sim.simulate import simulate
    prns = [1, 6, 9]
    paths = simulate(ROOT / "configs" / "scenarios" / "static_default.yaml", tmp_path / "p2.bin",
                     [("time.duration_s", 0.05), ("constellation.prns", prns), ("cn0.dbhz", 47.0),
                      ("frontend.format", "packed2_real"), ("frontend.sample_rate_hz", 16.368e6),
                      ("frontend.if_hz", 4.092e6), ("frontend.bit_order", "lsb_first"),
                      ("frontend.encoding", "twos_complement")], progress=False)
    import yaml
    frag = yaml.safe_load(open(paths["yaml"]))["input"]
    assert frag["format"] == "packed2_real" and frag["bit_order"] == "lsb_first"
    r = SampleReader(paths["if"], "packed2_real", 16.368e6, bit_order="lsb_first", encoding="twos_complement")
    assert r.n_samples == int(0.05 * 16.368e6)
    x = r.read(0, int(0.04 * 16.368e6))
    assert set(np.unique(x.real)) <= {-3.0, -1.0, 1.0, 3.0}
    found = {a.prn: a for a in search(x, 0, 16.368e6, 4.092e6, prns + [5, 17], coherent_ms=4,
                                      noncoherent=10, threshold=1.25) if a.detected}
    assert set(found) == set(prns), sorted(found)
    with h5py.File(paths["truth"]) as t:
        for p in prns:
            d = t[f"satellites/G{p:02d}/doppler_hz"][0]
            assert abs(found[p].doppler_hz - d) < 150, (p, found[p].doppler_hz, d)
