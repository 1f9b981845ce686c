import os
from typing import Any, Mapping, Optional, Union

import numpy as np
import numpy.typing as npt
import pandas as pd

SOURCE_ATTR: str
PathLike = Union[str, os.PathLike[str]]
Columns = Union[pd.DataFrame, Mapping[str, npt.ArrayLike]]

class RecordingWarning(UserWarning): ...

def read_recording(path: PathLike) -> pd.DataFrame: ...
def write_recording(data: Columns, path: PathLike) -> int: ...
def filter_recording(
    data: Columns,
    config: PathLike,
    *,
    smooth: bool = ...,
    lenient: bool = ...,
    prefix: str = ...,
    learn: Optional[PathLike] = ...,
    input_name: Optional[str] = ...,
) -> pd.DataFrame: ...
def simulate(
    preset: Optional[str] = ...,
    *,
    scenario: Optional[PathLike] = ...,
    duration: Optional[float] = ...,
    seed: Optional[int] = ...,
) -> pd.DataFrame: ...
