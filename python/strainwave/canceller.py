"""The joint's canceller as a stream: one sample or one block of rows at a time."""

from __future__ import annotations

import os
from typing import Any, Dict, List, Optional, Tuple, Union

import numpy as np
import pandas as pd

from . import _native
from .recording import SOURCE_ATTR, PathLike, _columns


class RippleCanceller:
    """The ripple and misalignment canceller of a joint config, with its state kept
    between calls: feed it sample by sample (:meth:`step`, a control loop) or block by
    block (:meth:`run`, arrays as they arrive). Running a whole recording through
    :meth:`run`, in one block or many, gives the numbers of :func:`strainwave.filter_recording`
    and ``strainwave filter`` bit for bit.

    Values are in the recording's units: each channel's ``scale``/``offset`` and the
    config's calibration are applied, as ``filter`` applies them. A sample that cannot be
    used (a NaN, an angle missing) is skipped with a flag, as ``filter --lenient`` does.

    The canceller runs under the do-no-harm guard, as ``filter`` does, unless the config
    sets ``filter.guard = false``: each order's correction is applied only once the data
    support it (``filter_flags`` bits 8–15 are the guard's, bits 16 and up mark the orders
    withheld), and :meth:`health` gives the summary ``filter`` prints. With ``learn`` a
    second, cold canceller learns beside the output, as ``filter --learn FILE`` does, and
    :meth:`save_learned` writes the file that command writes.

    Example::

        >>> c = sw.RippleCanceller.from_config("examples/joint-taghirad.toml")
        >>> rec = sw.simulate("taghirad", duration=2, seed=1)
        >>> out = c.run(rec)                 # dict of numpy arrays: torque, ripple, ...
        >>> torque_nm, flags = c.step(0.12, motor_angle=3.1, output_angle=0.031, time=2.0)
        >>> c.health()["mean_nis"]           # 1 when the model fits the data
        1.03...
        >>> [o[0] for o in c.learned()]      # the reference of each order
        ['relative', 'relative', 'relative', 'relative', 'output']
    """

    def __init__(self, native: Any) -> None:
        self._native = native

    @classmethod
    def from_config(
        cls,
        config: PathLike,
        learned: Optional[PathLike] = None,
        *,
        learn: Union[bool, PathLike] = False,
    ) -> "RippleCanceller":
        """The canceller of the joint config file ``config``, as ``strainwave filter``
        runs it (under the do-no-harm guard unless the config sets ``filter.guard =
        false``).

        ``learned``: a learned-coefficients file (as ``filter --learn`` writes) to run
        from instead of the config's ``filter.learned``. ``learn``: a cold canceller
        (the model's commissioning tuning, no priors) learns beside the output from every
        sample, as ``filter --learn FILE`` does; ``learn=FILE`` names the file it merges
        into (checked now to be this joint's, its discovered orders learned too),
        ``learn=True`` leaves the file to :meth:`save_learned`.

        Raises :class:`strainwave.StrainwaveError` with the command line's message for a
        bad config or learned file.

        Example::

            >>> c = sw.RippleCanceller.from_config("joint.toml", learn="learned.toml")
        """
        learn_into = None
        if isinstance(learn, (str, os.PathLike)):
            learn, learn_into = True, os.fspath(learn)
        elif not isinstance(learn, bool):
            raise TypeError(f"learn: expected a bool or a path, got {type(learn).__name__}")
        return cls(
            _native.RippleCanceller.from_config(
                os.fspath(config),
                None if learned is None else os.fspath(learned),
                learn=learn,
                learn_into=learn_into,
            )
        )

    def step(
        self,
        torque: float,
        motor_angle: float = float("nan"),
        output_angle: float = float("nan"),
        *,
        motor_velocity: float = float("nan"),
        expected_torque: Optional[float] = None,
        time: float = float("nan"),
    ) -> Tuple[float, int]:
        """One sample: the torque channel's reading, the angles (or the motor velocity,
        for ``filter.phase = "velocity"``), optionally the expected torque and the time
        (s; a step in time sets the sample's interval, else the config's rate is used).
        Returns the clean torque, N·m (ripple and misalignment removed, no added delay;
        with the guard, the raw torque where it holds the correction back), and the
        step's flags (``filter_flags`` bits).

        Example::

            >>> torque_nm, flags = c.step(0.12, 3.1, 0.031, time=0.001)
        """
        return self._native.step(
            float(torque),
            float(motor_angle),
            float(output_angle),
            motor_velocity=float(motor_velocity),
            expected_torque=None if expected_torque is None else float(expected_torque),
            time=float(time),
        )

    def run(self, data: Any, *, input_name: Optional[str] = None) -> Dict[str, np.ndarray]:
        """A block of rows: a DataFrame or a mapping of column name to array with the
        columns the config's ``[channels]`` name (other columns are ignored). The GIL is
        released while it runs. Returns the columns ``filter`` adds (``torque``,
        ``ripple``, ``misalignment``, ``innovation``, ``nis``, ``filter_flags``, and
        ``torque_denoised`` when the config sets ``filter.torque_bandwidth_hz``) as
        float64 arrays of the block's length. The state carries over to the next block.

        Example::

            >>> for block in (rec.iloc[k : k + 1000] for k in range(0, len(rec), 1000)):
            ...     out = c.run(block)
        """
        if input_name is None:
            input_name = (data.attrs.get(SOURCE_ATTR) if isinstance(data, pd.DataFrame) else None) or "<DataFrame>"
        wanted = {c for c in self._native.channel_columns if c is not None}
        if isinstance(data, pd.DataFrame) and wanted <= {str(c) for c in data.columns}:
            # Only the channels are converted (with a channel missing, every column goes
            # to the command line's error, which lists them).
            data = data[[c for c in data.columns if str(c) in wanted]]
        # A sample it cannot use is skipped with a flag, a text cell too (as `--lenient`).
        names, arrays = _columns(data, input_name, lenient=True)
        names_out, columns = self._native.run_columns(names, arrays, input_name=input_name)
        return dict(zip(names_out, columns))

    def learned(self) -> List[Tuple[str, float, bool, float, float, float]]:
        """One ``(reference, multiple, load_scaled, cos_nm, sin_nm, variance_nm2)`` per
        order. When learning: the entries of the file :meth:`save_learned` would write
        now (merged into the ``learn=FILE`` file as it was at the start). Otherwise: the
        output canceller's coefficients now.

        Example::

            >>> c.learned()[0]
            ('relative', 2.0, False, 0.2520612107099989, 0.44771890136520587, 1.3217677768605336e-06)
        """
        return self._native.learned()

    def save_learned(self, path: Optional[PathLike] = None, merge: bool = True) -> List[str]:
        """Writes what the learning canceller learned, the file ``strainwave filter
        --learn FILE`` writes: with ``merge`` and ``path`` existing, merged into it by
        covariance (after checking it is this joint's file); written atomically (a
        temporary file, synced, renamed). ``path`` defaults to the ``learn=FILE`` of
        :meth:`from_config`. Returns the report lines (orders discovered in the
        innovation, orders that learned nothing). Needs ``learn``.

        Example::

            >>> c = sw.RippleCanceller.from_config("joint.toml", learn="learned.toml")
            >>> c.run(sw.read_recording("commissioning.csv"))
            >>> c.save_learned()
            ['order analysis of the innovation: 132 candidate lines ..., 0 significant']
        """
        return self._native.save_learned(None if path is None else os.fspath(path), merge)

    def health(self) -> Optional[Dict[str, Any]]:
        """The do-no-harm guard's summary so far, the figures ``filter`` prints after a
        run: ``samples``, ``mean_nis`` (against ``expected_nis``, 1), the shares of the
        samples in pass-through (``pass_through_share``) and with an order stepped back
        (``contradicted_share``), ``applied_share`` (``(order, share)`` per order), its
        ``warnings`` and the printed ``lines``. ``None`` with ``filter.guard = false``.

        Example::

            >>> c.health()["applied_share"][0]
            ('2× relative', 0.97...)
        """
        return self._native.health()

    @property
    def guard(self) -> bool:
        """Whether the do-no-harm guard runs (the config's ``filter.guard``)."""
        return self._native.guard

    @property
    def learning(self) -> bool:
        """Whether a cold canceller learns beside the output (``learn``)."""
        return self._native.learning

    def reset(self) -> None:
        """Back to the state of a new canceller (the priors it started from kept).

        Example::

            >>> c.reset(); c.samples
            0
        """
        self._native.reset()

    @property
    def samples(self) -> int:
        """Samples stepped since the start or the last :meth:`reset`."""
        return self._native.samples

    @property
    def extrapolated(self) -> int:
        """Samples for which the calibration extrapolated beyond its speed table."""
        return self._native.extrapolated

    def __copy__(self) -> "RippleCanceller":
        # A shallow copy would wrap the same native state: stepping one would step both.
        raise TypeError(
            "RippleCanceller cannot be copied: its state is native; start another with "
            "RippleCanceller.from_config (from a file save_learned wrote, to carry what it learned)"
        )

    def __deepcopy__(self, memo: Any) -> "RippleCanceller":
        return self.__copy__()

    def __repr__(self) -> str:
        return f"RippleCanceller.from_config({self._native.config!r}) after {self.samples} samples"
