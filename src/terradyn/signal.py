"""The one zero-phase low-pass of terradyn (trials, SPH force records, noise estimates)."""
from __future__ import annotations

import numpy as np

from .errors import InputError, finite_array, integer, positive

#: Largest Butterworth order accepted.
MAX_ORDER = 12


def check_lowpass(fs: float, cutoff_hz: float, order: int = 4, field: str = "cutoff-hz") -> None:
    """Raise :class:`InputError` on ``field`` unless a cut-off of ``cutoff_hz`` can filter a
    record sampled at ``fs`` Hz (strictly below the Nyquist frequency fs / 2)."""
    fs = positive("sampling rate", fs, "Hz")
    cutoff_hz = positive(field, cutoff_hz, "Hz")
    order = integer("order", order, 1)
    if order > MAX_ORDER:
        raise InputError("order", f"must be <= {MAX_ORDER}, got {order}")
    if cutoff_hz >= fs / 2 * (1 - 1e-9):  # at Nyquist (to rounding of the sampling rate)
        raise InputError(field, f"must be below the Nyquist frequency {fs / 2:g} Hz of the "
                                f"{fs:g} Hz sampling, got {cutoff_hz:g} Hz")


def min_samples(order: int = 4) -> int:
    """Fewest samples :func:`lowpass` filters at ``order`` (scipy's default padding + 1)."""
    return 3 * (2 * ((int(order) + 1) // 2) + 1) + 1


def lowpass(x, fs: float, cutoff_hz: float, order: int = 4, field: str = "cutoff-hz") -> np.ndarray:
    """Zero-phase Butterworth low-pass of x (n,) sampled at fs (Hz): the filter runs forward
    and backward (``scipy.signal.sosfiltfilt``), so the effective order doubles and the
    phase lag is zero. A cut-off at or above Nyquist, or a record too short, is an error."""
    from scipy.signal import butter, sosfiltfilt

    check_lowpass(fs, cutoff_hz, order, field)
    x = finite_array("signal", x, ndim=1)
    sos = butter(int(order), float(cutoff_hz), btype="low", fs=float(fs), output="sos")
    padlen = 3 * (2 * len(sos) + 1)
    if len(x) <= padlen:
        raise InputError("signal", f"too short to filter with order {order}: need more than {padlen} "
                                   f"samples, got {len(x)}")
    return sosfiltfilt(sos, x)
