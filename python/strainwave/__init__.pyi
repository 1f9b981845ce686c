from ._native import OUTPUT_COLUMNS as OUTPUT_COLUMNS, StrainwaveError as StrainwaveError
from .recording import (
    filter_recording as filter_recording,
    read_recording as read_recording,
    simulate as simulate,
    write_recording as write_recording,
)

__version__: str
