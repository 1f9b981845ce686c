"""Type stubs of the Rust extension (use the functions of `strainwave` instead)."""

from typing import Optional

import numpy as np
import numpy.typing as npt

OUTPUT_COLUMNS: list[str]

class StrainwaveError(ValueError):
    """A strainwave error; the message is the command line's one line."""

def read_recording(path: str) -> tuple[list[str], list[npt.NDArray[np.float64]]]: ...
def write_recording(path: str, names: list[str], arrays: list[npt.NDArray[np.float64]]) -> int: ...
def filter_columns(
    config: str,
    names: list[str],
    arrays: list[npt.NDArray[np.float64]],
    *,
    input_name: str,
    smooth: bool = ...,
    lenient: bool = ...,
    prefix: str = ...,
    learn: Optional[str] = ...,
    scratch_dir: Optional[str] = ...,
) -> tuple[list[str], list[npt.NDArray[np.float64]], list[str], list[str], int]: ...
def simulate(
    preset: Optional[str] = ...,
    *,
    scenario: Optional[str] = ...,
    duration: Optional[float] = ...,
    seed: Optional[int] = ...,
) -> tuple[list[str], list[npt.NDArray[np.float64]]]: ...
