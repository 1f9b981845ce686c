"""The encoder-based torque estimator: ``strainwave identify`` and ``strainwave estimate``
on DataFrames (or recording files)."""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from typing import Any, Dict, Optional, Union

import pandas as pd

from . import _native
from .recording import SOURCE_ATTR, PathLike, _columns, _frame, read_recording

try:  # Python 3.11+
    import tomllib
except ModuleNotFoundError:  # pragma: no cover
    tomllib = None

Recording = Union[pd.DataFrame, PathLike]


def _name(data: Any, input_name: Optional[str]) -> str:
    if input_name is not None:
        return input_name
    return (data.attrs.get(SOURCE_ATTR) if isinstance(data, pd.DataFrame) else None) or "<DataFrame>"


def _run(data: Any, input_name: Optional[str]) -> Any:
    """A run as the native call takes it: a file name, or (name, column names, arrays)."""
    if isinstance(data, (str, os.PathLike)):
        return os.fspath(data)
    name = _name(data, input_name)
    names, arrays = _columns(data, name)
    return (name, names, arrays)


def _frame_of(data: Any) -> pd.DataFrame:
    return read_recording(data) if isinstance(data, (str, os.PathLike)) else data


@dataclass
class Identified:
    """What :func:`identify` found.

    ``model_text`` is the model file ``strainwave identify --out`` writes (read by
    :func:`estimate` and ``strainwave estimate --config``), ``model`` the same parsed,
    ``summary`` the JSON ``--summary-json`` writes (fits, parameters with standard
    errors, holdout scores, notes)."""

    model_text: str
    summary: Dict[str, Any]
    model: Dict[str, Any] = field(default_factory=dict)


def identify(
    loaded: Recording,
    config: PathLike,
    *,
    no_load: Optional[Recording] = None,
    out: Optional[PathLike] = None,
    holdout: Optional[int] = None,
    lenient: bool = False,
    allow_unconverged: bool = False,
    input_name: Optional[str] = None,
    no_load_name: Optional[str] = None,
) -> Identified:
    """Fits the kinematic error and the compliance of an encoder-based torque estimator:
    ``strainwave identify --config CONFIG --loaded LOADED [--no-load NO_LOAD]``.

    ``loaded`` (with a reference torque) and ``no_load`` are DataFrames or recording files
    with the columns the arm configuration's ``[channels]`` name. ``out=FILE`` writes the
    model file as the command line does; ``holdout=K`` scores the model on K blocks
    (``--holdout``), ``lenient=True`` skips rows with non-finite values or impossible reference torques (``--lenient``),
    ``allow_unconverged=True`` keeps a model whose fit did not converge. Errors name
    ``input_name`` / ``no_load_name`` (default: the file, else ``<DataFrame>``).

    Example::

        >>> found = sw.identify("loaded.csv", config="examples/arm-hda.toml", no_load="noload.csv",
        ...                     out="arm-model.toml")
        >>> found.summary["compliance"]["fit"]["r_squared"] > 0.99
        True
    """
    model_text, summary = _native.identify_runs(
        os.fspath(config),
        _run(loaded, input_name),
        None if no_load is None else _run(no_load, no_load_name),
        out=None if out is None else os.fspath(out),
        holdout=holdout,
        lenient=lenient,
        allow_unconverged=allow_unconverged,
    )
    model = tomllib.loads(model_text) if tomllib is not None else {}
    return Identified(model_text=model_text, summary=json.loads(summary), model=model)


def estimate(data: Recording, config: PathLike, *, input_name: Optional[str] = None) -> pd.DataFrame:
    """Link torque from the motor and link encoders with a model file written by
    :func:`identify`: ``strainwave estimate --config CONFIG``.

    Returns the input columns followed by ``torque``, ``torsion``, ``kinematic_error`` and
    ``estimate_flags`` (and ``current_torque`` when the model has friction), the command
    line's numbers bit for bit. The warnings the command line prints (encoder jumps, a
    sample rate it could not check) are in ``out.attrs["strainwave_warnings"]``.

    Example::

        >>> out = sw.estimate(sw.read_recording("arm.csv"), config="arm-model.toml")
        >>> out["torque"].iloc[-1]   # N·m
    """
    name = os.fspath(data) if isinstance(data, (str, os.PathLike)) and input_name is None else _name(data, input_name)
    frame = _frame_of(data)
    names, arrays = _columns(frame, name)
    added, columns, warning = _native.estimate_columns(os.fspath(config), names, arrays, input_name=name)
    out = _frame(names + added, arrays + columns)
    out.attrs["strainwave_warnings"] = warning.splitlines() if warning else []
    return out
