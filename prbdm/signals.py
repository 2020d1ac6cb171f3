"""Periods and frequencies measured from sampled signals: shared by :mod:`prbdm.simulate` (the
PRBDM and the truth's tip motions) and :mod:`prbdm.export` (a free vibration in MuJoCo), which
import it instead of each other (no import cycle)."""
from __future__ import annotations

import math

import numpy as np

__all__ = ["zero_crossing_period", "dominant_frequency", "decaying_window", "damped_frequency"]

#: a damped record's frequency is read while its first mode's envelope is above this fraction of
#: its start: above the integrator's noise (rtol 1e-9), and long enough for 2.6 damped periods at
#: zeta 0.7 (a least-squares sinusoid averages the noise; zero crossings do not: they stop at
#: CROSSING_FLOOR)
DECAY_FLOOR = 1e-7
CROSSING_FLOOR = 1e-4


def zero_crossing_period(t, y) -> float:
    """Mean period between upward zero crossings (linear interpolation); nan if fewer than 2."""
    t, y = np.asarray(t, float), np.asarray(y, float)
    up = np.flatnonzero((y[:-1] < 0) & (y[1:] >= 0))
    if up.size < 2:
        return math.nan
    tc = t[up] - y[up] * (t[up + 1] - t[up]) / (y[up + 1] - y[up])
    return float((tc[-1] - tc[0]) / (up.size - 1))


def dominant_frequency(t, y, guess: float, span: float = 0.3) -> float:
    """Frequency [rad/s] of the strongest sinusoid in ``y`` within ``guess * (1 +- span)``.

    For each trial frequency, a Hann-weighted least-squares fit of ``a cos(w t) + b sin(w t)``;
    the frequency that explains most of the signal is located by the peak of the zero-padded FFT
    and refined by Brent's method. Unlike a Fourier peak, the fit is exact for a pure sinusoid
    however few periods are recorded (no bias from the negative-frequency image); the window
    keeps modes several times faster from leaking in. Samples uniform in t.
    """
    from scipy.optimize import minimize_scalar

    t, y = np.asarray(t, float), np.asarray(y, float)
    W = np.hanning(t.size + 2)[1:-1]
    tc = t - (t[0] + t[-1]) / 2
    yw = W * (y - np.average(y, weights=W))

    def neg_fit(w):
        c, s = np.cos(w * tc), np.sin(w * tc)
        G = np.array([[np.sum(W * c * c), np.sum(W * c * s)], [0.0, np.sum(W * s * s)]])
        G[1, 0] = G[0, 1]
        r = np.array([yw @ c, yw @ s])
        return -float(r @ np.linalg.solve(G, r))

    # coarse: the peak of the zero-padded Fourier amplitude within the span
    pad = 8 * t.size
    dt = (t[-1] - t[0]) / (t.size - 1)
    freqs = 2 * np.pi * np.fft.rfftfreq(pad, dt)
    amp = np.abs(np.fft.rfft(yw, pad))
    inside = np.flatnonzero((freqs >= guess * (1 - span)) & (freqs <= guess * (1 + span)))
    if inside.size == 0:
        raise ValueError("dominant_frequency: the record is too short for this span")
    k = inside[np.argmax(amp[inside])]
    step = freqs[1]
    # fine: the best least-squares sinusoid within half a bin of the record either side
    res = minimize_scalar(neg_fit, bounds=(max(freqs[k] - 4 * step, step), freqs[k] + 4 * step),
                          method="bounded", options={"xatol": guess * 1e-12})
    return float(res.x)


def decaying_window(t, omega: float, zeta: float, floor: float = DECAY_FLOOR) -> np.ndarray:
    """(T,) bool: the samples of ``t`` [s] where a first mode of natural frequency ``omega``
    [rad/s] and damping ratio ``zeta`` still has ``floor`` of its starting envelope
    ``exp(-zeta omega t)``: later, what is left is the integrator's noise (and, above zeta about
    0.7, the overdamped higher modes, which then decay more slowly than the first)."""
    t = np.asarray(t, float)
    if zeta <= 0:
        return np.ones(t.shape, bool)
    return t - t[0] <= math.log(1 / floor) / (zeta * omega)


def damped_frequency(t, y, omega: float, zeta: float, floor: float = DECAY_FLOOR) -> float:
    """Damped first-mode frequency [rad/s] of a free response ``y`` whose first mode has natural
    frequency about ``omega`` [rad/s] and the known damping ratio ``zeta``: the known decay
    ``exp(-zeta omega t)`` is divided out, over :func:`decaying_window`, and the strongest
    sinusoid is found about ``omega sqrt(1 - zeta^2)`` (:func:`dominant_frequency`); nan where
    the window is too short for that search (zeta near 1). A decaying
    record read as it is gives a period biased by its decay (1 % at zeta 0.5, 7 % at 0.7); so
    read, the truth's measured period is within 5e-4 of its exact one up to zeta 0.72 on the
    measured panels (tests/test_simulate.py), and the error grows fast beyond."""
    t, y = np.asarray(t, float), np.asarray(y, float)
    keep = decaying_window(t, omega, zeta, floor)
    t, y = t[keep], y[keep]
    try:
        return dominant_frequency(t, y * np.exp(zeta * omega * (t - t[0])),
                                  omega * math.sqrt(1 - zeta ** 2))
    except ValueError:            # the first mode dies out within a fraction of its period
        return math.nan
