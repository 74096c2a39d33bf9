"""GeoSOT grid codes and the GeoSOT grid search for the initial value of Doppler positioning.

GeoSOT ("Geographical coordinate Subdividing grid with One-dimension-integer coding on 2^n Tree")
extends the longitude/latitude square to 512 deg x 512 deg and halves it recursively (a quadtree):
level 1 cells are 256 deg, level 9 cells 1 deg.  One degree is extended to 64' and one minute to 64''
so that the halving stays integral: levels 10-15 go from 32' to 1', levels 16-21 from 32'' to 1'',
and levels 22-32 halve the second down to 1/2048''.  Cells whose minutes or seconds would be >= 60 do
not exist; cells cut by the 60' / 60'' edge are smaller than nominal.

Each coordinate is coded on 32 bits:  [sign:1][degrees:8][minutes:6][seconds:6][1/2048 s:11].
A level-L cell is the pair of L-bit prefixes (latitude code, longitude code); its quadtree code
interleaves the two prefixes (one base-4 digit per level: 2 * lat_bit + lon_bit).

Grid search (initial value of the Doppler solvers)
--------------------------------------------------
At the cell centres (on the ellipsoid at a chosen height) the residual vector of all observations,
Y_i = f0 (v_i . e_i) / c - f_di (the predicted Doppler without receiver offset minus the measured one;
e_i the unit vector satellite -> receiver), is evaluated; with ``clock='fit'`` its mean (the
least-squares frequency offset) is removed.  All start-level cells of the region that sees every
observed satellite are searched; the ``keep`` best cells are then split into their four children level
by level down to the end level, and the centre with the smallest ||Y||_2 is the initial value.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import UserError
from ..gnss.geodesy import lla2ecef
from ..gnss.signals import C_LIGHT

MAX_LEVEL = 32
_FRAC_BITS = 11
_SEC_SHIFT = _FRAC_BITS                 # 11
_MIN_SHIFT = _SEC_SHIFT + 6             # 17
_DEG_SHIFT = _MIN_SHIFT + 6             # 23
_SIGN_SHIFT = _DEG_SHIFT + 8            # 31


# --------------------------------------------------------------------------------------------------
# Codes
# --------------------------------------------------------------------------------------------------
def encode(value_deg) -> np.ndarray:
    """32-bit GeoSOT code(s) of latitude or longitude value(s) in degrees."""
    v = np.asarray(value_deg, float)
    neg = v < 0
    mag = np.abs(v)
    # work in units of 1/2048 arc-second, then split into deg/min/sec/fraction
    units = np.floor(mag * 3600.0 * 2048.0 + 1e-6).astype(np.int64)
    frac = units % 2048
    secs_total = units // 2048
    sec = secs_total % 60
    mins_total = secs_total // 60
    mins = mins_total % 60
    deg = mins_total // 60
    if np.any(deg > 255):
        raise ValueError("|value| must be below 256 degrees")
    code = ((neg.astype(np.int64) << _SIGN_SHIFT) | (deg << _DEG_SHIFT) | (mins << _MIN_SHIFT)
            | (sec << _SEC_SHIFT) | frac)
    return code


def prefix(code, level: int) -> np.ndarray:
    """Level-L prefix of 32-bit coordinate codes (level 0: 0)."""
    return np.asarray(code, np.int64) >> (32 - level) if level > 0 else np.zeros_like(code)


def cell_of(lat_deg, lon_deg, level: int):
    """(lat_prefix, lon_prefix) of the level-L cell that contains the point(s)."""
    return prefix(encode(lat_deg), level), prefix(encode(lon_deg), level)


def quadtree_code(lat_prefix: int, lon_prefix: int, level: int) -> str:
    """Base-4 GeoSOT cell code 'G' + one digit per level (2 * lat bit + lon bit)."""
    digits = []
    for i in range(level - 1, -1, -1):
        digits.append(str(2 * ((int(lat_prefix) >> i) & 1) + ((int(lon_prefix) >> i) & 1)))
    return "G" + "".join(digits)


def nominal_size_deg(level: int) -> float:
    """Nominal cell edge at a level, in real degrees (1' = 1/60 deg)."""
    if level <= 9:
        return 2.0 ** (9 - level)
    if level <= 15:
        return 2.0 ** (15 - level) / 60.0
    if level <= 21:
        return 2.0 ** (21 - level) / 3600.0
    return 2.0 ** (32 - level) / 2048.0 / 3600.0


def prefix_extent(p, level: int, limit: float):
    """Real-degree extent [lo, hi] of level-L prefixes of one axis, clipped to [-limit, limit].

    Returns (lo, hi, valid); cells that do not exist (minutes/seconds >= 60, beyond the limit) have
    valid False.
    """
    p = np.asarray(p, np.int64)
    if level == 0:
        n = p.shape
        return np.full(n, -limit), np.full(n, limit), np.ones(n, bool)
    low = p << (32 - level)
    neg = (low >> _SIGN_SHIFT) & 1
    deg = (low >> _DEG_SHIFT) & 0xFF
    mins = (low >> _MIN_SHIFT) & 0x3F
    sec = (low >> _SEC_SHIFT) & 0x3F
    frac = low & 0x7FF
    valid = (mins < 60) & (sec < 60)
    lo_mag = deg + mins / 60.0 + (sec + frac / 2048.0) / 3600.0
    size = nominal_size_deg(level)
    hi_mag = lo_mag + size
    if 10 <= level <= 15:                       # cut at the end of the degree (60')
        hi_mag = np.minimum(hi_mag, deg + 1.0)
    elif 16 <= level <= 21:                     # cut at the end of the minute (60'')
        hi_mag = np.minimum(hi_mag, deg + (mins + 1) / 60.0)
    if level == 1:                              # the two 256-degree halves
        lo_mag = np.zeros(p.shape)
        hi_mag = np.full(p.shape, 256.0)
    lo = np.where(neg == 1, -hi_mag, lo_mag)
    hi = np.where(neg == 1, -lo_mag, hi_mag)
    lo_c, hi_c = np.maximum(lo, -limit), np.minimum(hi, limit)
    valid &= hi_c > lo_c
    return lo_c, hi_c, valid


@dataclass
class Cells:
    """A set of cells of one level: prefixes, centres and validity."""
    level: int
    lat_p: np.ndarray
    lon_p: np.ndarray

    def extents(self):
        """(lat_lo, lat_hi, lon_lo, lon_hi, valid) of every cell, real degrees clipped to +-90 / +-180."""
        la0, la1, vla = prefix_extent(self.lat_p, self.level, 90.0)
        lo0, lo1, vlo = prefix_extent(self.lon_p, self.level, 180.0)
        return la0, la1, lo0, lo1, vla & vlo

    def centres(self):
        """(lat, lon) of the cell centres, deg."""
        la0, la1, lo0, lo1, _ = self.extents()
        return 0.5 * (la0 + la1), 0.5 * (lo0 + lo1)

    def children(self) -> "Cells":
        """The four level + 1 children of every cell (only those that exist)."""
        lat = (self.lat_p[:, None] << 1) | np.array([0, 0, 1, 1])[None, :]
        lon = (self.lon_p[:, None] << 1) | np.array([0, 1, 0, 1])[None, :]
        c = Cells(self.level + 1, lat.ravel(), lon.ravel())
        return c.valid_only()

    def valid_only(self) -> "Cells":
        """The cells that exist (minutes and seconds < 60, inside +-90 / +-180 deg)."""
        v = self.extents()[4]
        return Cells(self.level, self.lat_p[v], self.lon_p[v])

    def __len__(self):
        return len(self.lat_p)


def cells_in_box(level: int, lat_lo, lat_hi, lon_lo, lon_hi, max_cells: int = 2_000_000) -> Cells:
    """All valid level-L cells that intersect a latitude/longitude box."""
    size = nominal_size_deg(level)
    step = size / 4.0                             # truncated cells are at least half nominal size
    n_lat = int(np.ceil((lat_hi - lat_lo) / step)) + 1
    n_lon = int(np.ceil((lon_hi - lon_lo) / step)) + 1
    if n_lat * n_lon > 16 * max_cells:
        raise UserError(f"GeoSOT start level {level} is too fine for a {lat_hi - lat_lo:.1f} x "
                        f"{lon_hi - lon_lo:.1f} deg search region; lower geosot.start_level")
    la = np.clip(np.linspace(lat_lo, lat_hi, n_lat), -90.0, 90.0 - 1e-12)
    lo = np.clip(np.linspace(lon_lo, lon_hi, n_lon), -180.0, 180.0 - 1e-12)
    lat_p = np.unique(prefix(encode(la), level))
    lon_p = np.unique(prefix(encode(lo), level))
    LA, LO = np.meshgrid(lat_p, lon_p, indexing="ij")
    return Cells(level, LA.ravel(), LO.ravel()).valid_only()


# --------------------------------------------------------------------------------------------------
# Doppler residual and grid search
# --------------------------------------------------------------------------------------------------
def doppler_residuals(points_ecef, sat_pos, sat_vel, doppler_hz, f0, clock: str = "fit"):
    """Residual vectors Y (M, K) at M points for K observations, and the fitted offsets (M,).

    Y_i = f0 (v_i . e_i) / c - f_di with e_i = (X - X_si) / |X - X_si| (satellite -> receiver), i.e.
    the modelled Doppler without receiver offset minus the measurement; with clock='fit' the
    least-squares offset (mean of -Y) is removed.
    """
    d = points_ecef[:, None, :] - sat_pos[None, :, :]
    rho = np.sqrt(np.einsum("mki,mki->mk", d, d))
    pred = (f0 / C_LIGHT) * np.einsum("ki,mki->mk", sat_vel, d) / rho
    Y = pred - doppler_hz[None, :]
    if clock == "fit":
        off = Y.mean(axis=1)
        return Y - off[:, None], -off
    return Y, np.zeros(len(Y))


def _region_boxes(sat_pos, mask_deg, margin_deg):
    """Lat/lon boxes that contain every point seeing at least one of the satellites."""
    from ..gnss.geodesy import ecef2lla
    lat, lon, h = ecef2lla(sat_pos)
    re = 6371e3
    el = np.radians(max(mask_deg - margin_deg, -10.0))
    # Earth central angle of the coverage circle of a satellite at height h, elevation el
    lam = np.degrees(np.arccos(np.clip(re * np.cos(el) / (re + h), -1, 1)) - el)
    lat_lo = max(-90.0, float(np.min(lat - lam)))
    lat_hi = min(90.0, float(np.max(lat + lam)))
    if lat_lo <= -89 or lat_hi >= 89:
        return [(lat_lo, lat_hi, -180.0, 180.0)]
    # longitude span, widened by the footprint at the highest latitude involved
    coslat = max(np.cos(np.radians(max(abs(lat_lo), abs(lat_hi)))), 1e-3)
    wid = float(np.max(lam)) / coslat
    ref = np.degrees(np.angle(np.mean(np.exp(1j * np.radians(lon)))))
    rel = (lon - ref + 180.0) % 360.0 - 180.0
    lo_, hi_ = ref + rel.min() - wid, ref + rel.max() + wid
    if hi_ - lo_ >= 360.0:
        return [(lat_lo, lat_hi, -180.0, 180.0)]
    boxes = []
    for a, b in ((lo_, hi_), (lo_ - 360, hi_ - 360), (lo_ + 360, hi_ + 360)):
        a, b = max(a, -180.0), min(b, 180.0)
        if b > a:
            boxes.append((lat_lo, lat_hi, a, b))
    return boxes


@dataclass
class GridResult:
    """Result of :func:`grid_search`: centre of the best cell (deg, deg, m and ECEF m), the fitted receiver
    frequency offset (Hz), the cell's level and prefixes, its cost ||Y||_2 (Hz), the cell diagonal (m), the
    number of cells evaluated and per level the centres and costs searched."""
    lat_deg: float
    lon_deg: float
    height_m: float
    ecef: np.ndarray
    freq_offset_hz: float
    level: int
    lat_prefix: int
    lon_prefix: int
    cost: float
    cell_size_m: float               # diagonal of the final cell
    n_evaluated: int
    history: list                    # per level: (level, centres (M, 2), costs (M,))

    @property
    def code(self) -> str:
        """GeoSOT code of the best cell ('G' + one base-4 digit per level)."""
        return quadtree_code(self.lat_prefix, self.lon_prefix, self.level)


def search_region(sat_pos, level: int, height_m: float, mask_deg: float, margin_deg: float) -> Cells:
    """Start-level cells whose centres see every satellite position above (mask - margin)."""
    sat_pos = np.asarray(sat_pos, float).reshape(-1, 3)
    cells = None
    for box in _region_boxes(sat_pos, mask_deg, margin_deg):
        c = cells_in_box(level, *box)
        cells = c if cells is None else Cells(level, np.r_[cells.lat_p, c.lat_p],
                                              np.r_[cells.lon_p, c.lon_p])
    lat, lon = cells.centres()
    pts = lla2ecef(lat, lon, height_m)
    up = pts / np.linalg.norm(pts, axis=1)[:, None]      # geocentric up is enough for a region test
    ok = np.ones(len(pts), bool)
    thr = np.sin(np.radians(mask_deg - margin_deg))
    for chunk in np.array_split(np.arange(len(sat_pos)), max(1, len(sat_pos) // 64)):
        d = sat_pos[None, chunk, :] - pts[:, None, :]
        s = np.einsum("mki,mi->mk", d, up) / np.linalg.norm(d, axis=2)
        ok &= np.all(s >= thr, axis=1)
    if not np.any(ok):                    # no common visibility region: fall back to the boxes
        return cells
    return Cells(level, cells.lat_p[ok], cells.lon_p[ok])


def grid_search(sat_pos, sat_vel, doppler_hz, f0, start_level=9, end_level=18, keep=32,
                height_m=0.0, clock="fit", elevation_mask_deg=10.0, mask_margin_deg=5.0,
                region: Cells | None = None) -> GridResult:
    """GeoSOT coarse-to-fine search of the receiver position minimising ||Y||_2.

    sat_pos, sat_vel (K, 3) and doppler_hz (K,) are all observations (any epochs) of a static
    receiver.  ``region`` (start-level cells) may be passed to reuse a precomputed search region.
    """
    sat_pos = np.asarray(sat_pos, float)
    sat_vel = np.asarray(sat_vel, float)
    z = np.asarray(doppler_hz, float)
    if len(z) < 2:
        raise UserError("GeoSOT grid search needs at least two Doppler observations")
    if not 1 <= start_level <= end_level <= MAX_LEVEL:
        raise UserError("GeoSOT levels must satisfy 1 <= start_level <= end_level <= 32")
    cells = region if region is not None else search_region(sat_pos, start_level, height_m,
                                                            elevation_mask_deg, mask_margin_deg)
    history, n_eval = [], 0
    best = None
    while True:
        lat, lon = cells.centres()
        pts = lla2ecef(lat, lon, height_m)
        Y, off = doppler_residuals(pts, sat_pos, sat_vel, z, f0, clock)
        cost = np.sqrt(np.einsum("mk,mk->m", Y, Y))
        n_eval += len(cost)
        history.append((cells.level, np.c_[lat, lon], cost))
        order = np.argsort(cost)
        i = order[0]
        best = (cells.level, int(cells.lat_p[i]), int(cells.lon_p[i]), lat[i], lon[i], cost[i], off[i])
        if cells.level >= end_level:
            break
        top = order[:keep]
        cells = Cells(cells.level, cells.lat_p[top], cells.lon_p[top]).children()
    level, lp, op, la, lo, c, off = best
    la0, la1, _ = prefix_extent(np.array([lp]), level, 90.0)
    lo0, lo1, _ = prefix_extent(np.array([op]), level, 180.0)
    dn = (la1[0] - la0[0]) * 111_320.0
    de = (lo1[0] - lo0[0]) * 111_320.0 * np.cos(np.radians(la))
    return GridResult(lat_deg=float(la), lon_deg=float(lo), height_m=height_m,
                      ecef=lla2ecef(la, lo, height_m), freq_offset_hz=float(off), level=level,
                      lat_prefix=lp, lon_prefix=op, cost=float(c), cell_size_m=float(np.hypot(dn, de)),
                      n_evaluated=n_eval, history=history)
