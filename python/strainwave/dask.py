"""A fleet of recordings on Dask: every recording filtered by the joint's canceller in
parallel, one task per recording, the command line's numbers bit for bit.

Example (a local cluster of two worker processes)::

    >>> from distributed import Client, LocalCluster
    >>> import strainwave.dask
    >>> client = Client(LocalCluster(n_workers=2, processes=True))
    >>> done = strainwave.dask.filter_many(["a.csv", "b.csv"], "joint.toml", out_dir="filtered")
    >>> [(d.output, d.rows) for d in done]
    [('filtered/a.csv', 600000), ('filtered/b.csv', 600000)]

The paths (recordings, config, output folder) must be readable and writable under the
same names on every worker: a shared file system, or the same checkout everywhere.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Any, List, Optional, Sequence, Union

import pandas as pd

from . import _native
from .recording import PathLike, filter_recording, read_recording


@dataclass(frozen=True)
class Filtered:
    """One recording's run on a worker."""

    #: The recording read.
    input: str
    #: The file written (``out_dir``), or ``None`` when the frame came back instead.
    output: Optional[str]
    #: Data rows.
    rows: int
    #: Warnings the command line prints for it.
    warnings: List[str]


def filter_file(
    path: PathLike,
    config: PathLike,
    out: Optional[PathLike] = None,
    *,
    smooth: bool = False,
    lenient: bool = False,
    prefix: str = "",
) -> Union[Filtered, pd.DataFrame]:
    """``strainwave filter --config CONFIG --in PATH --out OUT`` in this process: with
    ``out``, the recording is streamed from file to file by the extension in constant
    memory, as the command line does (no DataFrame is made), and a :class:`Filtered`
    returned; without it, the filtered frame is returned."""
    path = os.fspath(path)
    if out is None:
        return filter_recording(read_recording(path), config, smooth=smooth, lenient=lenient, prefix=prefix)
    out = os.fspath(out)
    rows, _notes, warnings, _extrapolated = _native.filter_file(
        os.fspath(config), path, out, smooth=smooth, lenient=lenient, prefix=prefix
    )
    return Filtered(path, out, rows, list(warnings))


def _output_path(out_dir: str, path: str, suffix: str) -> str:
    stem = os.path.basename(path)
    if suffix:
        root, ext = os.path.splitext(stem)
        stem = f"{root}{suffix}{ext}"
    return os.path.join(out_dir, stem)


def _filter_partition(part: pd.DataFrame, config: str, smooth: bool, lenient: bool, prefix: str) -> pd.DataFrame:
    out = filter_recording(part, config, smooth=smooth, lenient=lenient, prefix=prefix)
    out.index = part.index
    out.attrs.clear()
    return out


def filter_many(
    recordings: Union[Sequence[PathLike], Any],
    config: PathLike,
    *,
    out_dir: Optional[PathLike] = None,
    suffix: str = "",
    smooth: bool = False,
    lenient: bool = False,
    prefix: str = "",
    compute: bool = True,
) -> Any:
    """Filters many recordings on Dask (the active ``distributed.Client`` if there is
    one, else Dask's default scheduler), one task per recording.

    ``recordings`` is either

    - a list of recording paths: with ``out_dir`` each task writes
      ``out_dir/NAME`` (``suffix`` before the extension; CSV or Parquet by the name) and
      returns a :class:`Filtered`, which keeps results off the client; without it each
      task returns the filtered DataFrame;
    - a ``dask.dataframe.DataFrame`` with one recording per partition (a partitioned
      Parquet dataset read with ``dask.dataframe.read_parquet``): returns the filtered
      Dask DataFrame (lazy; ``compute`` does not apply).

    ``compute=False`` returns the list of ``dask.delayed`` objects instead of their results.
    """
    import dask
    import dask.dataframe as dd

    config = os.fspath(config)
    if isinstance(recordings, dd.DataFrame):
        meta = recordings._meta.copy()
        for c in _native.OUTPUT_COLUMNS:
            meta[prefix + c] = pd.Series(dtype="float64")
        return recordings.map_partitions(
            _filter_partition, config, smooth, lenient, prefix, meta=meta, enforce_metadata=False
        )
    if isinstance(recordings, (str, os.PathLike)):
        raise TypeError("recordings: expected a list of paths or a dask DataFrame, got one path")
    paths = [os.fspath(p) for p in recordings]
    if out_dir is not None:
        out_dir = os.fspath(out_dir)
        os.makedirs(out_dir, exist_ok=True)
        outs = [_output_path(out_dir, p, suffix) for p in paths]
        if len(set(outs)) != len(outs):
            raise ValueError("two recordings have the same file name; give them distinct names or use suffix")
    else:
        outs = [None] * len(paths)
    tasks = [
        dask.delayed(filter_file, pure=False)(p, config, o, smooth=smooth, lenient=lenient, prefix=prefix)
        for p, o in zip(paths, outs)
    ]
    if not compute:
        return tasks
    return list(dask.compute(*tasks))
