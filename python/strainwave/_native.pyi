"""Type stubs of the Rust extension (use the functions of `strainwave` instead)."""

from typing import Any, Optional

import numpy as np
import numpy.typing as npt

OUTPUT_COLUMNS: list[str]

class StrainwaveError(ValueError):
    """A strainwave error; the message is the command line's one line."""

def read_recording(path: str) -> tuple[list[str], tuple[list[str], list[npt.NDArray[np.float64]]]]: ...
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

class RippleCanceller:
    @staticmethod
    def from_config(
        config: str, learned: Optional[str] = ..., *, learn: bool = ..., learn_into: Optional[str] = ...
    ) -> "RippleCanceller": ...
    def step(
        self,
        torque: float,
        motor_angle: float = ...,
        output_angle: float = ...,
        *,
        motor_velocity: float = ...,
        expected_torque: Optional[float] = ...,
        time: float = ...,
    ) -> tuple[float, int]: ...
    def run_columns(
        self, names: list[str], arrays: list[npt.NDArray[np.float64]], *, input_name: str
    ) -> tuple[list[str], list[npt.NDArray[np.float64]]]: ...
    def learned(self) -> list[tuple[str, float, bool, float, float, float]]: ...
    def save_learned(self, path: Optional[str] = ..., merge: bool = ...) -> list[str]: ...
    def health(self) -> Optional[dict[str, Any]]: ...
    def reset(self) -> None: ...
    @property
    def guard(self) -> bool: ...
    @property
    def learning(self) -> bool: ...
    @property
    def samples(self) -> int: ...
    @property
    def extrapolated(self) -> int: ...
    @property
    def config(self) -> str: ...
    @property
    def channel_columns(self) -> list[Optional[str]]: ...

def welch_psd(
    x: npt.NDArray[np.float64],
    sample_rate_hz: float,
    nperseg: int,
    *,
    noverlap: Optional[int] = ...,
    nfft: Optional[int] = ...,
    window: Optional[npt.NDArray[np.float64]] = ...,
    detrend: str = ...,
    scaling: str = ...,
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]: ...
def stft_frames(
    x: npt.NDArray[np.float64],
    sample_rate_hz: float,
    nperseg: int,
    *,
    noverlap: Optional[int] = ...,
    nfft: Optional[int] = ...,
    window: Optional[npt.NDArray[np.float64]] = ...,
    detrend: str = ...,
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.complex128]]: ...
def order_slice_blocks(
    signal: npt.NDArray[np.float64],
    speed_rpm: npt.NDArray[np.float64],
    sample_rate_hz: float,
    order: float,
    *,
    revs_per_block: float = ...,
    initial_angle_rev: float = ...,
) -> list[npt.NDArray[np.float64]]: ...
def calibrate_experiments(
    model: str,
    experiments: list[tuple[str, npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.float64]]],
    *,
    inputs: str,
    description: str,
    speed_column: str = ...,
    with_offset: bool = ...,
    full_scale: Optional[float] = ...,
    bins: Optional[int] = ...,
    speed_edges: Optional[list[float]] = ...,
    degree: int = ...,
    extrapolation: str = ...,
) -> str: ...
def identify_runs(
    config: str,
    loaded: Any,
    no_load: Any = ...,
    *,
    out: Optional[str] = ...,
    holdout: Optional[int] = ...,
    lenient: bool = ...,
    allow_unconverged: bool = ...,
) -> tuple[str, str]: ...
def estimate_columns(
    config: str, names: list[str], arrays: list[npt.NDArray[np.float64]], *, input_name: str
) -> tuple[list[str], list[npt.NDArray[np.float64]], str]: ...
def fuse_columns(
    config: str,
    names: list[str],
    arrays: list[npt.NDArray[np.float64]],
    *,
    input_name: str,
    method: str = ...,
    reference: Optional[str] = ...,
) -> tuple[list[str], list[npt.NDArray[np.float64]], str]: ...
