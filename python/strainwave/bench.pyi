from typing import Optional

import pandas as pd

from .encoders import Recording
from .recording import PathLike

METHODS: tuple[str, ...]

def fuse(
    data: Recording,
    config: PathLike,
    *,
    method: str = ...,
    reference: Optional[str] = ...,
    input_name: Optional[str] = ...,
) -> pd.DataFrame: ...
