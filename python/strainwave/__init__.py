"""strainwave for Python: strain wave gear joint recordings, the ripple and misalignment
canceller and the joint's twin, on pandas DataFrames and numpy arrays.

The numbers are the command line's, bit for bit: the same Rust code runs (with the GIL
released), and errors are :class:`StrainwaveError` with the message ``strainwave`` prints.

Example::

    >>> import strainwave as sw
    >>> rec = sw.simulate("taghirad", duration=2, seed=1)
    >>> out = sw.filter_recording(rec, config="examples/joint-taghirad.toml")
    >>> list(out.columns[-6:])
    ['torque', 'ripple', 'misalignment', 'innovation', 'nis', 'filter_flags']
"""

from ._native import OUTPUT_COLUMNS, StrainwaveError
from .bench import fuse
from .calibrate import calibrate
from .encoders import Identified, estimate, identify
from .canceller import RippleCanceller
from .recording import RecordingWarning, filter_recording, read_recording, simulate, write_recording
from .spectra import orders, sample_rate_hz, stft, welch

__all__ = [
    "Identified",
    "OUTPUT_COLUMNS",
    "RecordingWarning",
    "RippleCanceller",
    "StrainwaveError",
    "calibrate",
    "estimate",
    "filter_recording",
    "fuse",
    "identify",
    "orders",
    "read_recording",
    "sample_rate_hz",
    "simulate",
    "stft",
    "welch",
    "write_recording",
]
__version__ = "0.1.0"
