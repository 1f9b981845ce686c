from dataclasses import dataclass
from typing import Any, List, Optional, Sequence, Union

import pandas as pd

from .recording import PathLike

@dataclass(frozen=True)
class Filtered:
    input: str
    output: Optional[str]
    rows: int
    warnings: List[str]

def filter_file(
    path: PathLike,
    config: PathLike,
    out: Optional[PathLike] = ...,
    *,
    smooth: bool = ...,
    lenient: bool = ...,
    prefix: str = ...,
) -> Union[Filtered, pd.DataFrame]: ...
def filter_many(
    recordings: Union[Sequence[PathLike], Any],
    config: PathLike,
    *,
    out_dir: Optional[PathLike] = ...,
    suffix: str = ...,
    smooth: bool = ...,
    lenient: bool = ...,
    prefix: str = ...,
    compute: bool = ...,
) -> Any: ...
