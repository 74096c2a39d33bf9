"""Galileo I/NAV page coding on E1-B (Galileo OS SIS ICD issue 1.1, sections 4.3.2 and 5.1.9.4): the sync
pattern, the CRC-24Q, the K = 7 rate-1/2 convolutional code with its soft-decision Viterbi decoder, the
30 x 8 block interleaver, and the even / odd page parts of a nominal page (see receiver.gnss.gal_inav for
the page layout; this module turns a 128-bit word into the 2 x 250 symbols of a page and back).
"""
from __future__ import annotations

import numpy as np
from numba import njit

from .lnav import bits_to_int, int_to_bits

SYNC = (0, 1, 0, 1, 1, 0, 0, 0, 0, 0)
SYNC_LEN = 10
_SYNC_ARR = np.array(SYNC, np.uint8)
PART_SYMBOLS = 250           # per page part, sync included (1 s)
CODED_SYMBOLS = 240
PART_BITS = 120              # information + tail
INFO_BITS = 114
TAIL_BITS = 6
WORD_BITS = 128
CRC_BITS = 24
N_COLS, N_ROWS = 30, 8       # block interleaver (ICD Table 28)
G1, G2 = 0o171, 0o133        # generator polynomials, bit 6 = the current input bit
K = 7

# ------------------------------------------------------------------------------------------ CRC-24Q
#: P(X) of ICD Eq. 23 (exponents); G(X) = (1 + X) P(X), Eq. 22
_P_EXPONENTS = (23, 17, 13, 12, 11, 9, 8, 7, 5, 3, 0)
_P = sum(1 << k for k in _P_EXPONENTS)
CRC24_POLY = _P ^ (_P << 1)          # (1 + X) P(X): 25 bits, X^24 the top term


def _crc_table():
    t = np.zeros(256, np.int64)
    for b in range(256):
        r = b << 16
        for _ in range(8):
            r <<= 1
            if r & (1 << 24):
                r ^= CRC24_POLY
        t[b] = r & 0xFFFFFF
    return t


_CRC_TABLE = _crc_table()


def crc24q(bits) -> int:
    """CRC of ICD 5.1.9.4 over a bit sequence (m1 = first = MSB): the remainder of m(X) X^24 / G(X) as a
    24-bit integer (p1 = its MSB).  Leading zeros do not change it, so the bits are padded in front to whole
    bytes and run through a byte table."""
    b = np.asarray(bits, np.uint8).ravel()
    pad = (-len(b)) % 8
    by = np.packbits(np.concatenate([np.zeros(pad, np.uint8), b]))
    r = 0
    for x in by.tolist():
        r = ((r << 8) & 0xFFFFFF) ^ int(_CRC_TABLE[((r >> 16) ^ x) & 0xFF])
    return r


# ------------------------------------------------------------------------------------ FEC, interleaver
def _parity(x: int) -> int:
    return bin(x).count("1") & 1


#: per encoder state (the 6 previous bits, most recent in bit 5) and input bit: (G1 symbol, G2 symbol)
#: with G2 inverted, and the next state
_OUT = np.zeros((64, 2, 2), np.uint8)
_NEXT = np.zeros((64, 2), np.int64)
for _s in range(64):
    for _b in range(2):
        _reg = (_b << 6) | _s                          # bit 6 = current input, bit 0 = oldest
        _OUT[_s, _b, 0] = _parity(_reg & G1)
        _OUT[_s, _b, 1] = 1 - _parity(_reg & G2)       # G2 inverted (ICD Figure 13)
        _NEXT[_s, _b] = _reg >> 1


def conv_encode(bits) -> np.ndarray:
    """Rate-1/2 K = 7 encoding from the zero state: 2 symbols (0/1) per bit, G1 first, G2 inverted."""
    s = 0
    b = np.asarray(bits, np.uint8).ravel()
    out = np.empty(2 * len(b), np.uint8)
    for i, x in enumerate(b.tolist()):
        out[2 * i] = _OUT[s, x, 0]
        out[2 * i + 1] = _OUT[s, x, 1]
        s = int(_NEXT[s, x])
    return out


@njit(cache=True, nogil=True)
def _viterbi(soft, out_tab, next_tab, n_bits):
    """Soft-decision Viterbi (correlation metric) from state 0 to state 0: soft > 0 means symbol 0."""
    neg = -1e30
    metric = np.full(64, neg)
    metric[0] = 0.0
    prev_state = np.zeros((n_bits, 64), np.int64)
    prev_bit = np.zeros((n_bits, 64), np.uint8)
    new = np.empty(64)
    for i in range(n_bits):
        s0 = soft[2 * i]
        s1 = soft[2 * i + 1]
        new[:] = neg
        for s in range(64):
            m = metric[s]
            if m == neg:
                continue
            for b in range(2):
                ns = next_tab[s, b]
                bm = (s0 if out_tab[s, b, 0] == 0 else -s0) + (s1 if out_tab[s, b, 1] == 0 else -s1)
                if m + bm > new[ns]:
                    new[ns] = m + bm
                    prev_state[i, ns] = s
                    prev_bit[i, ns] = b
        metric[:] = new
    bits = np.empty(n_bits, np.uint8)
    s = 0
    for i in range(n_bits - 1, -1, -1):
        bits[i] = prev_bit[i, s]
        s = prev_state[i, s]
    return bits


def viterbi_decode(soft) -> np.ndarray:
    """Information bits (0/1, tail included) of soft symbols (float, > 0 = symbol 0, e.g. prompt sums with
    the polarity resolved; hard 0/1 symbols are taken as +1/-1) encoded by :func:`conv_encode` and ended
    by the zero tail."""
    a = np.asarray(soft)
    if a.dtype == np.uint8 or a.dtype == bool:
        a = 1.0 - 2.0 * a.astype(np.float64)
    a = np.ascontiguousarray(a, np.float64)
    return _viterbi(a, _OUT, _NEXT, len(a) // 2)


def interleave(sym):
    """240 encoded symbols -> the transmitted order: written into 30 columns of 8, read row by row."""
    return np.asarray(sym).reshape(N_COLS, N_ROWS).T.reshape(-1)


def deinterleave(sym):
    """Inverse of :func:`interleave` (works on soft symbols)."""
    return np.asarray(sym).reshape(N_ROWS, N_COLS).T.reshape(-1)


def encode_part(bits114) -> np.ndarray:
    """114 page-part bits -> the 250 transmitted symbols (0/1): sync, then the encoded, interleaved part."""
    b = np.asarray(bits114, np.uint8).ravel()
    if len(b) != INFO_BITS:
        raise ValueError(f"an I/NAV page part has {INFO_BITS} bits, got {len(b)}")
    coded = conv_encode(np.concatenate([b, np.zeros(TAIL_BITS, np.uint8)]))
    return np.concatenate([np.array(SYNC, np.uint8), interleave(coded)])


def decode_part(soft250) -> np.ndarray:
    """250 polarity-resolved soft symbols of a page part (sync first, > 0 = symbol 0) -> its 114 bits."""
    s = np.asarray(soft250)
    if s.dtype == np.uint8 or s.dtype == bool:
        s = 1.0 - 2.0 * s.astype(np.float64)
    return viterbi_decode(deinterleave(s[SYNC_LEN:SYNC_LEN + CODED_SYMBOLS]))[:INFO_BITS]


# -------------------------------------------------------------------------------------------- pages
def page_parts(word128, reserved1: int = 0, sar: int = 0, spare: int = 0, reserved2: int = 0):
    """A 128-bit word -> (even part, odd part) of a nominal E1-B page, 114 bits each, CRC filled in."""
    w = np.asarray(word128, np.uint8).ravel()
    if len(w) != WORD_BITS:
        raise ValueError(f"an I/NAV word has {WORD_BITS} bits, got {len(w)}")
    even = np.concatenate([[0, 0], w[:112]]).astype(np.uint8)
    odd = np.concatenate([[1, 0], w[112:], int_to_bits(reserved1, 40), int_to_bits(sar, 22),
                          int_to_bits(spare, 2)]).astype(np.uint8)
    crc = crc24q(np.concatenate([even, odd]))
    odd = np.concatenate([odd, int_to_bits(crc, CRC_BITS), int_to_bits(reserved2, 8)]).astype(np.uint8)
    return even, odd


def page_word(even114, odd114):
    """(word 128 bits, CRC ok) of a received even + odd part pair of a nominal page; None when the parts
    are not even (first bit 0) then odd (1), or either is an alert page."""
    e = np.asarray(even114, np.uint8)
    o = np.asarray(odd114, np.uint8)
    if e[0] != 0 or o[0] != 1 or e[1] != 0 or o[1] != 0:
        return None
    crc_ok = crc24q(np.concatenate([e, o[:82]])) == bits_to_int(o[82:106])
    return np.concatenate([e[2:114], o[2:18]]), crc_ok
