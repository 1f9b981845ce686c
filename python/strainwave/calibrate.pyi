from typing import Any, Dict, Optional, Sequence, Union

import pandas as pd

from .recording import PathLike

MODELS: tuple[str, ...]

def calibrate(
    data: Union[pd.DataFrame, Sequence[pd.DataFrame]],
    reference: str,
    sensor: str,
    *,
    model: str = ...,
    speed: Optional[str] = ...,
    experiment_column: Optional[str] = ...,
    with_offset: bool = ...,
    full_scale: Optional[float] = ...,
    bins: Optional[int] = ...,
    speed_edges: Optional[Sequence[float]] = ...,
    degree: int = ...,
    extrapolation: str = ...,
    out: Optional[PathLike] = ...,
) -> Dict[str, Any]: ...
