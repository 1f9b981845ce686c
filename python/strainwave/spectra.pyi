from typing import Any, Dict, Optional, Sequence

import numpy as np
import numpy.typing as npt
import pandas as pd

MAX_STEP_RATIO: float
MAX_SPEED_BINS: int

def sample_rate_hz(data: Any) -> float: ...
def welch(
    data: Any,
    signal: Optional[str] = ...,
    *,
    sample_rate_hz: Optional[float] = ...,
    nperseg: int = ...,
    noverlap: Optional[int] = ...,
    nfft: Optional[int] = ...,
    window: Any = ...,
    detrend: str = ...,
    scaling: str = ...,
) -> pd.DataFrame: ...
def stft(
    data: Any,
    signal: Optional[str] = ...,
    *,
    sample_rate_hz: Optional[float] = ...,
    nperseg: int = ...,
    noverlap: Optional[int] = ...,
    nfft: Optional[int] = ...,
    window: Any = ...,
    detrend: str = ...,
) -> Dict[str, npt.NDArray[Any]]: ...
def orders(
    data: Any,
    signal: str,
    speed: str,
    orders: Sequence[float],
    *,
    speed_unit: str = ...,
    revs_per_block: float = ...,
    speed_bin: float = ...,
) -> Dict[str, pd.DataFrame]: ...
