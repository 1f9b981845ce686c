"""The motor test bench's torque fusion: ``strainwave fuse`` on DataFrames (or recording
files)."""

from __future__ import annotations

import os
from typing import Optional

import pandas as pd

from . import _native
from .encoders import Recording, _frame_of, _name
from .recording import PathLike, _columns, _frame

#: The fusion methods, as ``strainwave fuse --method`` takes them.
METHODS = ("online-corrected", "complementary", "spectral", "corrected")


def fuse(
    data: Recording,
    config: PathLike,
    *,
    method: str = "online-corrected",
    reference: Optional[str] = None,
    input_name: Optional[str] = None,
) -> pd.DataFrame:
    """Hybrid torque from a torsion shaft and two accelerometers:
    ``strainwave fuse --config CONFIG --method METHOD [--reference COLUMN]``.

    Returns the input columns followed by ``fused_torque``, the command line's numbers bit
    for bit. ``online-corrected`` and ``complementary`` stream; ``spectral`` and
    ``corrected`` work on the whole recording. What the command line prints (the online
    design's response, and with ``reference`` the fused torque's worst gain and phase
    error against that column) is in ``out.attrs["strainwave_report"]``.

    Example::

        >>> rec = sw.read_recording("bench.csv")   # strainwave simulate --preset kit-bench
        >>> out = sw.fuse(rec, config="examples/bench-kit.toml", reference="true_dut_torque")
        >>> print(out.attrs["strainwave_report"])
    """
    name = os.fspath(data) if isinstance(data, (str, os.PathLike)) and input_name is None else _name(data, input_name)
    frame = _frame_of(data)
    names, arrays = _columns(frame, name)
    added, columns, said = _native.fuse_columns(
        os.fspath(config), names, arrays, input_name=name, method=method, reference=reference
    )
    out = _frame(names + added, arrays + columns)
    out.attrs["strainwave_report"] = said
    return out
