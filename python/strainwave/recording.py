"""Recordings as pandas DataFrames, and the joint's canceller over them."""

from __future__ import annotations

import os
import warnings
from typing import Any, Mapping, Optional, Sequence, Union

import numpy as np
import pandas as pd

from . import _native
from ._native import StrainwaveError

#: Where :func:`read_recording` keeps the file name in ``DataFrame.attrs`` (messages
#: about the frame then name the file, as the command line's do).
SOURCE_ATTR = "strainwave_source"

PathLike = Union[str, "os.PathLike[str]"]


def _frame(names: Sequence[str], arrays: Sequence[np.ndarray], source: Optional[str] = None) -> pd.DataFrame:
    df = pd.DataFrame(dict(zip(names, arrays)), copy=False)
    if len(set(names)) != len(names):
        # dict() would merge repeated names; keep every column as the file has it.
        df = pd.concat([pd.Series(a, name=n) for n, a in zip(names, arrays)], axis=1)
    if source is not None:
        df.attrs[SOURCE_ATTR] = source
    return df


def _columns(data: Any, input_name: str, lenient: bool = False) -> tuple[list[str], list[np.ndarray]]:
    """Column names and contiguous float64 arrays of a DataFrame or a mapping of arrays.
    A column whose first value is text (a state, a category) is left out with a
    :class:`RecordingWarning`, as the command line leaves out a file's text column. An
    empty string is a missing value (NaN); other text further down a column of numbers is
    an error naming its row, or with ``lenient`` a NaN counted in one warning."""
    if isinstance(data, pd.DataFrame):
        items = [(str(c), data[c]) for c in data.columns] if data.columns.is_unique else [
            (str(c), data.iloc[:, k]) for k, c in enumerate(data.columns)
        ]
    elif isinstance(data, Mapping):
        items = [(str(k), v) for k, v in data.items()]
    else:
        raise TypeError(f"expected a pandas DataFrame or a mapping of column name to array, got {type(data).__name__}")
    names, arrays = [], []
    unreadable: list[tuple[int, str, Any]] = []
    for name, values in items:
        # As the command line refuses a header that names a column twice: which one the
        # config means is not known.
        if name in names:
            raise StrainwaveError(f"{input_name}: column `{name}` appears twice in the header")
        try:
            a = np.ascontiguousarray(np.asarray(values, dtype=np.float64))
        except (TypeError, ValueError):
            row, value = _first_text(values)
            if row == 1:
                warnings.warn(
                    f"{input_name}: column `{name}` holds text in data row 1: left out", RecordingWarning, stacklevel=3
                )
                continue
            if row > 1 and not lenient:
                raise StrainwaveError(f"{input_name}: row {row}, column `{name}`: `{value}` is not a number") from None
            a, texts = _numbers_or_nan(values)
            unreadable += [(k, name, v) for k, v in texts]
        if a.ndim != 1:
            raise StrainwaveError(f"{input_name}: column `{name}`: expected one dimension, got shape {a.shape}")
        names.append(name)
        arrays.append(a)
    if unreadable:
        row, name, value = min(unreadable, key=lambda u: u[0])
        warnings.warn(
            f"{input_name}: {len(unreadable)} cell(s) that are not numbers read as NaN, the first at row {row}, "
            f"column `{name}`: `{value}`",
            RecordingWarning,
            stacklevel=3,
        )
    return names, arrays


def _number(v: Any) -> Optional[float]:
    """``v`` as a number: an empty string is NaN (a missing value); other text is None."""
    if isinstance(v, str) and not v.strip():
        return float("nan")
    try:
        return float(np.asarray(v, dtype=np.float64))
    except (TypeError, ValueError):
        return None


def _first_text(values: Any) -> tuple[int, Any]:
    """The first value (1-based row) of a column that is not a number, nor empty."""
    for k, v in enumerate(np.asarray(values, dtype=object).ravel()):
        if _number(v) is None:
            return k + 1, v
    return 0, ""


def _numbers_or_nan(values: Any) -> tuple[np.ndarray, list[tuple[int, Any]]]:
    """A column with text: NaN for each cell that is not a number; those cells (1-based row)."""
    cells = np.asarray(values, dtype=object).ravel()
    numbers = [_number(v) for v in cells]
    texts = [(k + 1, v) for k, (v, x) in enumerate(zip(cells, numbers)) if x is None]
    a = np.array([np.nan if x is None else x for x in numbers], dtype=np.float64)
    return a, texts


class RecordingWarning(UserWarning):
    """What a reader warns of as the command line does: a log cut short (the rows before
    the cut are read), messages at a repeated time, channels left out."""


def read_recording(path: PathLike) -> pd.DataFrame:
    """Reads a whole recording, in any format the command line reads (CSV, Parquet, MCAP,
    rosbag2 `.db3` and folders, by the file's name), into a DataFrame of float64 columns in the file's order. What the
    reader warns of is raised as :class:`RecordingWarning` and kept in
    ``df.attrs["strainwave_warnings"]``.

    Example::

        >>> rec = sw.read_recording("run.csv")
        >>> rec["time"].iloc[:2].tolist()
        [0.0, 0.001]
    """
    path = os.fspath(path)
    warned, (names, arrays) = _native.read_recording(path)
    df = _frame(names, arrays, source=path)
    df.attrs["strainwave_warnings"] = list(warned)
    for w in warned:
        warnings.warn(f"{path}: {w}", RecordingWarning, stacklevel=2)
    return df


def write_recording(data: Any, path: PathLike) -> int:
    """Writes a DataFrame (or mapping of arrays) to CSV or Parquet (by the file's name) as
    ``strainwave`` writes its outputs; returns the rows written. CSV text keeps every
    float64 exactly (shortest round-trip form)."""
    path = os.fspath(path)
    names, arrays = _columns(data, path)
    return _native.write_recording(path, names, arrays)


def filter_recording(
    data: Any,
    config: PathLike,
    *,
    smooth: bool = False,
    lenient: bool = False,
    prefix: str = "",
    learn: Optional[PathLike] = None,
    input_name: Optional[str] = None,
) -> pd.DataFrame:
    """The joint's canceller over a recording: ``strainwave filter --config CONFIG``.

    ``data`` is a DataFrame (or a mapping of column name to array) with the columns the
    joint config's ``[channels]`` name. Returns the input columns followed by ``torque``,
    ``ripple``, ``misalignment``, ``innovation``, ``nis`` and ``filter_flags`` (each with
    ``prefix``), the command line's numbers bit for bit. ``smooth=True`` runs the offline
    smoother (``--smooth``), ``lenient=True`` goes on over bad rows (``--lenient``),
    ``learn=FILE`` writes the learned coefficients (``--learn FILE``).

    Notes and warnings the command line prints are in ``out.attrs["strainwave_notes"]``
    and ``out.attrs["strainwave_warnings"]``. Errors name ``input_name`` (default: the
    file :func:`read_recording` read, else ``<DataFrame>``) and the data row, 1-based.

    Example::

        >>> rec = sw.read_recording("taghirad.csv")
        >>> out = sw.filter_recording(rec, config="examples/joint-taghirad.toml")
        >>> out["torque"].iloc[-1]   # N·m, ripple and misalignment removed
    """
    if input_name is None:
        input_name = (data.attrs.get(SOURCE_ATTR) if isinstance(data, pd.DataFrame) else None) or "<DataFrame>"
    names, arrays = _columns(data, input_name, lenient)
    added, columns, notes, warnings, extrapolated = _native.filter_columns(
        os.fspath(config),
        names,
        arrays,
        input_name=input_name,
        smooth=smooth,
        lenient=lenient,
        prefix=prefix,
        learn=None if learn is None else os.fspath(learn),
    )
    out = _frame(names + added, arrays + columns)
    out.attrs["strainwave_notes"] = list(notes)
    out.attrs["strainwave_warnings"] = list(warnings)
    out.attrs["strainwave_extrapolated"] = int(extrapolated)
    return out


def simulate(
    preset: Optional[str] = None,
    *,
    scenario: Optional[PathLike] = None,
    duration: Optional[float] = None,
    seed: Optional[int] = None,
) -> pd.DataFrame:
    """The joint's twin: ``strainwave simulate --preset NAME`` (or ``--scenario FILE``) with
    ``--duration`` (s) and ``--seed``, as a DataFrame (measured channels, then ``true_*``).

    Example::

        >>> df = sw.simulate("taghirad", duration=10, seed=1)
        >>> len(df)
        10000
    """
    names, arrays = _native.simulate(
        preset, scenario=None if scenario is None else os.fspath(scenario), duration=duration, seed=seed
    )
    return _frame(names, arrays)
