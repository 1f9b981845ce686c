"""Spectra of one signal: Welch's PSD, the short-time Fourier transform and order slices
against speed (``strainwave orders``), on numpy arrays or DataFrame columns.

The spectral conventions are scipy's (``scipy.signal.welch`` / ``stft`` segments, windows,
detrending and scaling), computed by the Rust analysis crate with the GIL released.
"""

from __future__ import annotations

import math
from typing import Any, Dict, Optional, Sequence, Tuple

import numpy as np
import pandas as pd

from . import _native
from ._native import StrainwaveError
from .recording import SOURCE_ATTR

#: A time step more than this many times the typical one is a gap (as the command line's
#: spectral commands say).
MAX_STEP_RATIO = 100.0
#: At most this many speed bins in an order table.
MAX_SPEED_BINS = 4096
#: The largest signal magnitude the order analysis takes (its squares summed must not
#: overflow), as the command line's.
MAX_SPECTRAL_VALUE = 1e100
#: The largest speed magnitude, rpm, as the command line's.
MAX_SPEED_RPM = 1e7


def _name(data: Any) -> str:
    return (data.attrs.get(SOURCE_ATTR) if isinstance(data, pd.DataFrame) else None) or "<DataFrame>"


def _column(data: Any, name: str, flag: str) -> np.ndarray:
    if name not in data:
        raise StrainwaveError(f"{flag}: no column `{name}` in {_name(data)}")
    try:
        return np.ascontiguousarray(np.asarray(data[name], dtype=np.float64))
    except (TypeError, ValueError) as e:
        raise StrainwaveError(f"{_name(data)}: column `{name}`: not numbers ({e})") from None


def sample_rate_hz(data: Any) -> float:
    """The sample rate of a recording from its ``time`` column (s), as the command line's
    spectral commands take it: ``time`` finite and increasing on every row, no step more
    than 100 typical (median) steps; the rate is ``(rows − 1) / (last − first)``. Errors
    name the 1-based row.

    Example::

        >>> sw.sample_rate_hz(sw.simulate("taghirad", duration=1, seed=1))
        1000.0
    """
    path = _name(data)
    time = _column(data, "time", "time")
    if len(time) < 2:
        raise StrainwaveError(f"{path}: needs at least 2 samples, got {len(time)}")
    steps = np.diff(time)
    bad = np.flatnonzero(~(np.isfinite(time[1:]) & (steps > 0)))
    if bad.size:
        k = int(bad[0])
        raise StrainwaveError(
            f"{path}: row {k + 2}, column `time`: {_num_debug(time[k + 1])} s does not come after {_num_debug(time[k])} s of the row before"
        )
    if not math.isfinite(time[0]):
        raise StrainwaveError(f"{path}: row 1, column `time`: {_num(time[0])} is not a time")
    typical = np.sort(steps)[len(steps) // 2]
    far = np.flatnonzero(steps > MAX_STEP_RATIO * typical)
    if far.size:
        k = int(far[0])
        raise StrainwaveError(
            f"{path}: row {k + 2}, column `time`: a step of {_num(steps[k])} s, more than {_num(MAX_STEP_RATIO)} times "
            f"the typical {_num(typical)} s; this command needs an evenly sampled recording (fix the gap, or split the recording)"
        )
    dt = (time[-1] - time[0]) / (len(time) - 1)
    return 1.0 / dt


def _not_finite(v: float) -> Optional[str]:
    """`NaN`, `inf` or `-inf` as Rust prints them; `None` for a finite float."""
    if math.isnan(v):
        return "NaN"
    if math.isinf(v):
        return "inf" if v > 0 else "-inf"
    return None


def _num(v: float) -> str:
    """A float as Rust's `{}` prints it (shortest round trip, no exponent, `inf`/`NaN`)."""
    v = float(v)
    if (special := _not_finite(v)) is not None:
        return special
    r = repr(v)
    if "e" in r or "E" in r:
        r = np.format_float_positional(v, unique=True, trim="-")
    return r[:-2] if r.endswith(".0") else r


def _num_debug(v: float) -> str:
    """A float as Rust's `{:?}` prints it (shortest round trip, `1e308`, `4.0`, `inf`, `NaN`)."""
    v = float(v)
    if (special := _not_finite(v)) is not None:
        return special
    r = repr(v)
    if "e" in r:
        mantissa, exponent = r.split("e")
        return f"{mantissa}e{int(exponent)}"
    return r


def _signal(data: Any, signal: Optional[str], sample_rate: Optional[float]) -> Tuple[np.ndarray, float]:
    """The signal and its rate: a DataFrame's column (rate from ``time`` unless given) or an
    array with ``sample_rate_hz``."""
    if isinstance(data, (pd.DataFrame, dict)):
        if signal is None:
            raise StrainwaveError("signal: name the column to analyse (signal=...)")
        x = _column(data, signal, "signal")
        return x, float(sample_rate) if sample_rate is not None else sample_rate_hz(data)
    if sample_rate is None:
        raise StrainwaveError("sample_rate_hz: needed with an array (a DataFrame gives it by its `time` column)")
    x = np.ascontiguousarray(np.asarray(data, dtype=np.float64))
    if x.ndim != 1:
        raise StrainwaveError(f"signal: expected one dimension, got shape {x.shape}")
    return x, float(sample_rate)


def _window(window: Any, nperseg: int) -> Optional[np.ndarray]:
    if window is None or (isinstance(window, str) and window in ("hann", "hanning")):
        return None
    if isinstance(window, str):
        if window in ("boxcar", "rectangular", "rect"):
            return np.ones(nperseg)
        raise StrainwaveError(f"window: `{window}` is not hann or boxcar (or pass the coefficients)")
    return np.ascontiguousarray(np.asarray(window, dtype=np.float64))


def welch(
    data: Any,
    signal: Optional[str] = None,
    *,
    sample_rate_hz: Optional[float] = None,
    nperseg: int = 256,
    noverlap: Optional[int] = None,
    nfft: Optional[int] = None,
    window: Any = "hann",
    detrend: str = "constant",
    scaling: str = "density",
) -> pd.DataFrame:
    """Welch's averaged periodogram of one signal, with ``scipy.signal.welch``'s
    conventions (periodic Hann by default, ``noverlap = nperseg // 2``, one-sided, mean of
    the segments; a signal shorter than ``nperseg`` is an error rather than a shorter
    window). ``data``: a DataFrame and the ``signal`` column (the rate from ``time``), or
    an array and ``sample_rate_hz``. Returns a DataFrame of ``frequency_hz`` and ``psd``
    (unit²/Hz; unit² with ``scaling="spectrum"``).

    Example::

        >>> rec = sw.read_recording("bench.csv")   # strainwave simulate --preset kit-bench --out bench.csv
        >>> p = sw.welch(rec, "accel_torque", nperseg=4096)
        >>> p.loc[p["psd"].idxmax(), "frequency_hz"]
    """
    x, fs = _signal(data, signal, sample_rate_hz)
    f, p = _native.welch_psd(
        x, fs, int(nperseg), noverlap=noverlap, nfft=nfft, window=_window(window, nperseg), detrend=detrend, scaling=scaling
    )
    return pd.DataFrame({"frequency_hz": f, "psd": p})


def stft(
    data: Any,
    signal: Optional[str] = None,
    *,
    sample_rate_hz: Optional[float] = None,
    nperseg: int = 256,
    noverlap: Optional[int] = None,
    nfft: Optional[int] = None,
    window: Any = "hann",
    detrend: str = "constant",
) -> Dict[str, np.ndarray]:
    """The short-time Fourier transform of one signal, amplitude-scaled: a sinusoid
    ``A cos(2π f t + φ)`` on a bin (not DC or Nyquist) reads ``A·exp(jφ')``, ``φ'`` its
    phase at the segment start. Segments as :func:`welch` (default overlap
    ``nperseg // 8``, as ``scipy.signal.spectrogram``), no padding at the ends.

    Returns ``{"frequency_hz": (bins,), "time_s": (frames,) segment centres from the
    first sample, "frames": (frames, bins) complex128}``.

    Example::

        >>> s = sw.stft(np.cos(2 * np.pi * 100 * np.arange(1000) / 1000), sample_rate_hz=1000, nperseg=200)
        >>> round(abs(s["frames"][2, 20]), 9)
        1.0
    """
    x, fs = _signal(data, signal, sample_rate_hz)
    f, t, frames = _native.stft_frames(
        x, fs, int(nperseg), noverlap=noverlap, nfft=nfft, window=_window(window, nperseg), detrend=detrend
    )
    return {"frequency_hz": f, "time_s": t, "frames": frames}


def orders(
    data: Any,
    signal: str,
    speed: str,
    orders: Sequence[float],
    *,
    speed_unit: str = "rpm",
    revs_per_block: float = 8.0,
    speed_bin: float = 200.0,
) -> Dict[str, pd.DataFrame]:
    """Order slices: the amplitude and phase of each order (cycles per revolution) of
    ``signal`` against the speed column ``speed`` (``rpm`` or ``rad-s``), in angle-domain
    blocks of ``revs_per_block`` revolutions overlapping by half; ``strainwave orders``.

    Returns ``{"blocks": DataFrame(order, time_s, speed_rpm, amplitude, phase_rad) per
    block, "table": DataFrame per speed bin of ``speed_bin`` rpm with blocks in it}``;
    the table has ``speed_low_rpm``, ``speed_high_rpm`` and, per order ``o``,
    ``{o}x_amplitude`` (mean) and ``{o}x_phase_deg`` (circular mean): the numbers
    ``strainwave orders`` prints (NaN where the command prints a dash).

    Example::

        >>> rec = sw.read_recording("bench.csv")   # strainwave simulate --preset kit-bench --out bench.csv
        >>> t = sw.orders(rec, "accel_torque", "speed_rpm", [6, 12])["table"]
        >>> list(t.columns)
        ['speed_low_rpm', 'speed_high_rpm', '6x_amplitude', '6x_phase_deg', '12x_amplitude', '12x_phase_deg']
    """
    path = _name(data)
    x = _column(data, signal, "--signal")
    # As the command line: a spectrum sums squares, which overflow beyond this.
    big = np.flatnonzero(np.abs(x) > MAX_SPECTRAL_VALUE)
    if big.size:
        i = int(big[0])
        raise StrainwaveError(
            f"{path}: row {i + 1}, column `{signal}`: {_num_debug(x[i])} is beyond ±1e100, where its spectrum would overflow"
        )
    fs = sample_rate_hz(data)
    raw = _column(data, speed, "--speed")
    if speed_unit not in ("rpm", "rad-s", "rad_s"):
        raise StrainwaveError(f"--speed-unit: `{speed_unit}` is not one of rpm, rad-s")
    v = raw * (60.0 / (2 * math.pi)) if speed_unit in ("rad-s", "rad_s") else raw.copy()
    bad = np.flatnonzero(~np.isfinite(v))
    if bad.size:
        i = int(bad[0])
        raise StrainwaveError(f"{path}: row {i + 1}, column `{speed}`: speed {_num_debug(raw[i])} is not finite")
    fast = np.flatnonzero(np.abs(v) > MAX_SPEED_RPM)
    if fast.size:
        i = int(fast[0])
        raise StrainwaveError(f"{path}: row {i + 1}, column `{speed}`: speed {_num_debug(v[i])} rpm is beyond ±1e7 rpm")
    mean = math.fsum(v) / max(len(v), 1) if len(v) else float("nan")
    if math.isnan(mean) or mean <= 0.0:
        raise StrainwaveError(
            f"{path}: --speed: column `{speed}` is zero or negative (mean {mean:.3f} rpm); negate a reverse run"
        )
    if not (math.isfinite(speed_bin) and speed_bin > 0):
        raise StrainwaveError(f"--speed-bin: must be positive, got {_num_debug(speed_bin)}")
    top_k = int(np.argmax(v)) if len(v) else 0
    top = max(float(v[top_k]), 0.0) if len(v) else 0.0
    nbins = math.floor(top / speed_bin) + 1
    if nbins > MAX_SPEED_BINS:
        raise StrainwaveError(
            f"{path}: row {top_k + 1}, column `{speed}`: {_num_debug(top)} rpm in --speed-bin {_num_debug(speed_bin)} rpm bins needs "
            f"more than {MAX_SPEED_BINS} bins (a glitch in the speed? fix it, or widen --speed-bin)"
        )
    if not (math.isfinite(revs_per_block) and revs_per_block >= 1.0):
        raise StrainwaveError(f"--revs-per-block: must be at least 1 and finite, got {_num(revs_per_block)}")
    blocks = []
    table = {
        "speed_low_rpm": np.arange(nbins) * float(speed_bin),
        "speed_high_rpm": (np.arange(nbins) + 1) * float(speed_bin),
    }
    seen = np.zeros(nbins, dtype=bool)
    for o in orders:
        o = float(o)
        if not (math.isfinite(o) and o > 0):
            raise StrainwaveError(f"--order: must be positive, got {_num(o)}")
        try:
            t, s, a, p = _native.order_slice_blocks(x, v, fs, o, revs_per_block=float(revs_per_block))
        except StrainwaveError as e:
            raise StrainwaveError(f"--order {_num(o)}: {e}") from None
        blocks.append(pd.DataFrame({"order": np.full(len(t), o), "time_s": t, "speed_rpm": s, "amplitude": a, "phase_rad": p}))
        # Mean amplitude and circular mean phase of the blocks in each speed bin, summed
        # in block order as the command line sums them.
        b = np.minimum(np.floor(np.maximum(s, 0.0) / speed_bin).astype(np.int64), nbins - 1)
        n = np.bincount(b, minlength=nbins)
        amp, cos, sin = (np.zeros(nbins) for _ in range(3))
        for k, bk in enumerate(b):
            amp[bk] += a[k]
            cos[bk] += math.cos(p[k])
            sin[bk] += math.sin(p[k])
        with np.errstate(invalid="ignore", divide="ignore"):
            table[f"{_num(o)}x_amplitude"] = np.where(n > 0, amp / n, np.nan)
        table[f"{_num(o)}x_phase_deg"] = np.where(n > 0, np.degrees(np.arctan2(sin, cos)), np.nan)
        seen |= n > 0
    table = pd.DataFrame(table)[seen].reset_index(drop=True)
    return {"blocks": pd.concat(blocks, ignore_index=True), "table": table}
