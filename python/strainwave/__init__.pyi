from ._native import OUTPUT_COLUMNS as OUTPUT_COLUMNS, StrainwaveError as StrainwaveError
from .bench import fuse as fuse
from .calibrate import calibrate as calibrate
from .encoders import Identified as Identified, estimate as estimate, identify as identify
from .canceller import RippleCanceller as RippleCanceller
from .recording import (
    RecordingWarning as RecordingWarning,
    filter_recording as filter_recording,
    read_recording as read_recording,
    simulate as simulate,
    write_recording as write_recording,
)

from .spectra import (
    orders as orders,
    sample_rate_hz as sample_rate_hz,
    stft as stft,
    welch as welch,
)

__version__: str
