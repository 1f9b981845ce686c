"""Sensor calibration from experiments: ``strainwave calibrate`` on DataFrames."""

from __future__ import annotations

import math
import os
from typing import Any, Dict, List, Optional, Sequence, Union

import numpy as np
import pandas as pd

from . import _native
from ._native import StrainwaveError
from .recording import SOURCE_ATTR, PathLike
from .spectra import _num, _num_debug

try:  # Python 3.11+
    import tomllib
except ModuleNotFoundError:  # pragma: no cover
    tomllib = None

MODELS = ("gain", "static", "dynamic", "speed-table", "speed-poly")


def _source(df: pd.DataFrame, k: int, count: int) -> str:
    src = df.attrs.get(SOURCE_ATTR)
    return src if src else ("<DataFrame>" if count == 1 else f"<DataFrame {k + 1}>")


def _column(df: pd.DataFrame, path: str, name: str, option: str) -> np.ndarray:
    if name not in df.columns:
        cols = ", ".join(str(c) for c in df.columns)
        raise StrainwaveError(f"{path}: no column `{name}` for {option} (columns: {cols})")
    try:
        c = np.asarray(df[name], dtype=np.float64)
    except (TypeError, ValueError) as e:
        raise StrainwaveError(f"{path}: column `{name}`: not numbers ({e})") from None
    bad = np.flatnonzero(~np.isfinite(c))
    if bad.size:
        r = int(bad[0])
        raise StrainwaveError(
            f"{path}: row {r + 1}, column `{name}`: {_num(c[r])} is not a finite number; "
            "calibration data must be finite (fix or drop the row)"
        )
    return c


#: How many times its column's range a reference or sensor value may be (the command
#: line's limit: a glitch or a unit slip that a fit would follow), and the fewest rows
#: checked. The range is the largest magnitude once the largest 1 % (at least 3) are set aside.
OUTLIER_FACTOR = 100.0
OUTLIER_MIN_ROWS = 20


def _refuse_outlier(c: np.ndarray, path: str, name: str) -> None:
    if len(c) < OUTLIER_MIN_ROWS:
        return
    size = np.sort(np.abs(c))
    scale = float(size[len(size) - 1 - max(len(size) // 100, 3)])
    if scale == 0.0:
        return
    far = np.flatnonzero(np.abs(c) > OUTLIER_FACTOR * scale)
    if far.size:
        r = int(far[0])
        raise StrainwaveError(
            f"{path}: row {r + 1}: `{name}` = {_num_debug(c[r])} is over {_num(OUTLIER_FACTOR)} times the column's "
            f"range (its largest magnitude {_num_debug(scale)} without the top 1 %); a glitch or a unit slip? "
            "Fix or drop the row"
        )


def calibrate(
    data: Union[pd.DataFrame, Sequence[pd.DataFrame]],
    reference: str,
    sensor: str,
    *,
    model: str = "gain",
    speed: Optional[str] = None,
    experiment_column: Optional[str] = None,
    with_offset: bool = False,
    full_scale: Optional[float] = None,
    bins: Optional[int] = None,
    speed_edges: Optional[Sequence[float]] = None,
    degree: int = 1,
    extrapolation: str = "clamp",
    out: Optional[PathLike] = None,
) -> Dict[str, Any]:
    """Fits a sensor calibration: ``strainwave calibrate``.

    ``data``: one DataFrame per experiment (a list: several ``--in``), or one DataFrame
    with ``experiment_column`` numbering the experiments. ``reference``: the applied
    torque column (N·m); ``sensor``: the bridge voltage or raw reading; ``speed``: rad/s,
    for the speed models. ``model``: ``gain`` (``T = g V``; ``with_offset=True`` adds an
    offset), ``static``/``dynamic`` (``T = α x + β``), ``speed-table`` (``bins`` or
    ``speed_edges``), ``speed-poly`` (``degree``); ``extrapolation`` outside the speeds:
    ``clamp``, ``linear``, ``reject``.

    Returns ``{"file": the calibration file as a dict (``None`` before Python 3.11),
    "toml": its text}``, the file
    ``calibrate --out`` writes (its ``description`` names the DataFrames' files, or
    ``<DataFrame>``); ``out=PATH`` also writes it there, for ``[calibration] file``.
    Errors are the command line's messages.

    Example::

        >>> # strainwave simulate --preset taghirad --procedure locked-wg --out locked.csv
        >>> cal = sw.calibrate(sw.read_recording("locked.csv"), "reference_torque", "bridge_voltage",
        ...                    experiment_column="experiment")
        >>> cal["file"]["gain_nm_per_v"]
        6.611407434438008
    """
    frames: List[pd.DataFrame] = [data] if isinstance(data, pd.DataFrame) else list(data)
    if not frames:
        raise StrainwaveError("calibrate: no experiments (give one DataFrame or a list of them)")
    if model not in MODELS:
        raise StrainwaveError(f"--model: `{model}` is not one of {', '.join(MODELS)}")
    speed_model = model in ("speed-table", "speed-poly")
    experiments = []
    names = []
    for k, df in enumerate(frames):
        if not isinstance(df, pd.DataFrame):
            raise TypeError(f"expected pandas DataFrames, got {type(df).__name__}")
        path = _source(df, k, len(frames))
        names.append(path)
        if len(df) == 0:
            raise StrainwaveError(f"{path}: no data rows")
        ref = _column(df, path, reference, "--reference")
        sen = _column(df, path, sensor, "--sensor")
        _refuse_outlier(ref, path, reference)
        _refuse_outlier(sen, path, sensor)
        if speed is not None:
            spd = _column(df, path, speed, "--speed")
        elif speed_model:
            raise StrainwaveError(f"--model {model} needs --speed COL")
        else:
            spd = np.empty(0)
        name = os.path.basename(path) if df.attrs.get(SOURCE_ATTR) else path
        if experiment_column is None:
            experiments.append((name, ref, sen, spd))
            continue
        e = _column(df, path, experiment_column, "--experiment-column")
        # Experiments in order of first appearance.
        keys, first = np.unique(e, return_index=True)
        for key in keys[np.argsort(first)]:
            rows = e == key
            label = f"{name} exp {_num(key)}" if len(frames) > 1 else f"exp {_num(key)}"
            experiments.append((label, ref[rows], sen[rows], spd[rows] if spd.size else spd))
    joined = ", ".join(names)
    description = (
        f"strainwave calibrate --model {model}: reference `{reference}`, sensor `{sensor}`, "
        f"{len(experiments)} experiment(s) from {joined}"
    )
    text = _native.calibrate_experiments(
        model,
        [(l, np.ascontiguousarray(r), np.ascontiguousarray(s), np.ascontiguousarray(v)) for l, r, s, v in experiments],
        inputs=joined,
        description=description,
        speed_column=speed or "",
        with_offset=with_offset,
        full_scale=None if full_scale is None else float(full_scale),
        bins=bins,
        speed_edges=None if speed_edges is None else [float(x) for x in speed_edges],
        degree=int(degree),
        extrapolation=extrapolation,
    )
    if out is not None:
        with open(os.fspath(out), "w", encoding="utf-8") as f:
            f.write(text)
    return {"file": tomllib.loads(text) if tomllib else None, "toml": text}
