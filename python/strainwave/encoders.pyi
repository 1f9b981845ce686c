import os
from typing import Any, Dict, Optional, Union

import pandas as pd

from .recording import PathLike

Recording = Union[pd.DataFrame, PathLike]

class Identified:
    model_text: str
    summary: Dict[str, Any]
    model: Dict[str, Any]
    def __init__(self, model_text: str, summary: Dict[str, Any], model: Dict[str, Any] = ...) -> None: ...

def identify(
    loaded: Recording,
    config: PathLike,
    *,
    no_load: Optional[Recording] = ...,
    out: Optional[PathLike] = ...,
    holdout: Optional[int] = ...,
    lenient: bool = ...,
    allow_unconverged: bool = ...,
    input_name: Optional[str] = ...,
    no_load_name: Optional[str] = ...,
) -> Identified: ...
def estimate(data: Recording, config: PathLike, *, input_name: Optional[str] = ...) -> pd.DataFrame: ...
