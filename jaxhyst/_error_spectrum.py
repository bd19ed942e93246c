"""Where a tracking error lies in frequency: its RMS in octave bands.

A compensator that leaves 0.5 % of the stroke RMS can leave it at the reference's
fundamental (a gain or phase error of the model's loop), at its harmonics (the loop's
shape), in a slow drift below it, or in a high-frequency ring after each step (a lag
the model lacks); each asks for a different fix. The bands split the error's mean
square exactly (Parseval): the squares of the band RMS values add up to the squared
RMS of the whole error.
"""

from typing import Any

import equinox as eqx
import numpy as np
from jaxtyping import ArrayLike, Float

from ._uniform import uniform_series


class ErrorSpectrum(eqx.Module):
    """A tracking error's RMS in frequency bands.

    - `low`, `high`: the band edges in Hz. The first band is the mean error alone
      (0 Hz); then octaves [2^k / T, 2^(k+1) / T) from the record's lowest
      resolved frequency 1/T up to the Nyquist frequency (the last band includes it).
    - `rms`: the error's RMS in each band, in the error's units; their squares sum
      to the squared RMS of the whole error.
    - `stroke`: the reference's peak-to-peak range the percentages refer to.
    """

    low: np.ndarray = eqx.field(converter=lambda v: np.asarray(v, float))
    high: np.ndarray = eqx.field(converter=lambda v: np.asarray(v, float))
    rms: np.ndarray = eqx.field(converter=lambda v: np.asarray(v, float))
    stroke: float = eqx.field(converter=float)

    def __repr__(self) -> str:
        bands = ", ".join(
            ("mean" if hi == 0 else f"{lo:.3g}-{hi:.3g} Hz") + f": {p:.3g} %"
            for lo, hi, p in zip(self.low, self.high, self.percent_of_stroke())
        )
        return f"ErrorSpectrum({bands})"

    @property
    def total_rms(self) -> float:
        """The RMS of the whole error (the bands' root sum of squares)."""
        return float(np.sqrt(np.sum(self.rms**2)))

    def percent_of_stroke(self) -> np.ndarray:
        """Each band's RMS in % of `stroke` (NaN when the stroke is zero)."""
        scale = 100.0 / self.stroke if self.stroke > 0 else float("nan")
        return self.rms * scale

    def shares(self) -> np.ndarray:
        """Each band's share (0-1) of the error's mean square (zeros for a zero
        error)."""
        power = self.rms**2
        total = float(np.sum(power))
        return power / total if total > 0 else np.zeros_like(power)

    def dominant(self) -> tuple[float, float, float]:
        """(low, high, share): the band holding the largest part of the error's mean
        square, and that share (0-1)."""
        shares = self.shares()
        index = int(np.argmax(shares))
        return float(self.low[index]), float(self.high[index]), float(shares[index])

    def to_json(self) -> dict[str, Any]:
        """A JSON-ready dict: the bands as lists, in Hz and in % of the stroke."""
        return {
            "low_hz": self.low.tolist(),
            "high_hz": self.high.tolist(),
            "rms": self.rms.tolist(),
            "rms_percent_of_stroke": self.percent_of_stroke().tolist(),
            "stroke": self.stroke,
        }


def error_spectrum(
    times: Float[ArrayLike, " n"],
    error: Float[ArrayLike, " n"],
    *,
    stroke: float,
) -> ErrorSpectrum:
    """The RMS of `error` (sampled at the uniformly spaced `times`) in octave bands,
    with percentages of `stroke` (the reference's peak-to-peak range): where in
    frequency a tracking error lies. See `ErrorSpectrum`."""
    owner = "error_spectrum"
    _, e, dt = uniform_series(owner, times, error, name="error", minimum=4)
    if not (np.isfinite(stroke) and stroke >= 0):
        raise ValueError(f"{owner}: stroke must be finite and >= 0, got {stroke!r}.")
    n = e.size
    spectrum = np.fft.rfft(e)
    weight = np.full(spectrum.size, 2.0)
    weight[0] = 1.0
    if n % 2 == 0:
        weight[-1] = 1.0  # the Nyquist bin appears once
    power = weight * np.abs(spectrum) ** 2 / n**2  # sums to mean(e**2)
    resolution = 1.0 / (n * dt)
    nyquist = 0.5 / dt
    # Bin k (k >= 1) lies in octave floor(log2(k)): [2^j, 2^(j+1)) times 1/T.
    octave = np.floor(np.log2(np.arange(1, spectrum.size))).astype(int)
    count = int(octave[-1]) + 1 if octave.size else 0
    rms = [np.sqrt(power[0])]
    rms += list(np.sqrt(np.bincount(octave, weights=power[1:], minlength=count)))
    low = [0.0] + [resolution * 2.0**j for j in range(count)]
    high = [0.0] + [min(resolution * 2.0 ** (j + 1), nyquist) for j in range(count)]
    return ErrorSpectrum(low, high, rms, stroke)
