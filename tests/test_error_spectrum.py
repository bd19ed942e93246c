"""Where a tracking error lies in frequency: `jh.error_spectrum`."""

import numpy as np
import pytest

import jaxhyst as jh


def _times(seconds=8.0, rate=250.0):
    return np.arange(0.0, seconds, 1 / rate)


@pytest.mark.parametrize("count", [2000, 2001])  # even and odd: the Nyquist bin
def test_the_bands_split_the_mean_square_exactly(count):
    t = np.arange(count) / 250.0
    error = np.random.default_rng(0).normal(size=count) + 0.2
    spectrum = jh.error_spectrum(t, error, stroke=4.0)
    np.testing.assert_allclose(spectrum.total_rms, np.sqrt(np.mean(error**2)))
    # The first band is the mean alone; the octaves tile (0, Nyquist].
    assert spectrum.high[0] == 0 and spectrum.rms[0] == pytest.approx(abs(error.mean()))
    np.testing.assert_allclose(spectrum.low[2:], spectrum.high[1:-1])
    np.testing.assert_allclose(spectrum.high[1:-1] / spectrum.low[1:-1], 2.0, rtol=0)
    assert 1.0 < spectrum.high[-1] / spectrum.low[-1] <= 2.0  # the last ends at Nyquist
    assert spectrum.low[1] == pytest.approx(250.0 / count)
    assert spectrum.high[-1] == pytest.approx(125.0)
    np.testing.assert_allclose(
        spectrum.percent_of_stroke(), 100 * spectrum.rms / 4.0, rtol=1e-14
    )


def test_a_tone_lies_in_its_own_band():
    t = _times()  # 1/T = 0.125 Hz: 3 Hz lies in the octave 2-4 Hz
    error = 0.5 * np.sin(2 * np.pi * 3.0 * t) + 0.05 * np.sin(2 * np.pi * 40.0 * t)
    spectrum = jh.error_spectrum(t, error, stroke=10.0)
    low, high, share = spectrum.dominant()
    assert (low, high) == (2.0, 4.0)
    assert share == pytest.approx(0.25 / (0.25 + 0.0025), rel=1e-9)
    index = int(np.argmax(spectrum.low == 32.0))
    assert spectrum.rms[index] == pytest.approx(0.05 / np.sqrt(2), rel=1e-9)
    record = spectrum.to_json()
    assert record["rms_percent_of_stroke"][index] == pytest.approx(
        100 * 0.05 / np.sqrt(2) / 10.0, rel=1e-9
    )


def test_a_compensation_reports_where_its_predicted_error_lies():
    model = jh.PiezoBoucWen.paper_table4(3)
    path = jh.sample(jh.paper_u1(), 200.0)
    t = np.asarray(path.times)
    reference = np.asarray(jh.simulate(model, path))
    result = jh.compensate(model, t, reference, limits=(0.0, 4.0))
    spectrum = result.error_spectrum()
    np.testing.assert_allclose(
        spectrum.total_rms, result.tracking()["rms_error"], rtol=1e-12, atol=1e-300
    )
    assert spectrum.stroke == pytest.approx(np.ptp(reference))


@pytest.mark.parametrize(
    ("times", "error", "stroke", "words"),
    [
        (np.arange(10.0), np.zeros(9), 1.0, "equal length"),
        (np.arange(10.0), np.full(10, np.nan), 1.0, "finite"),
        (np.array([0.0, 1.0, 3.0, 4.0, 5.0]), np.zeros(5), 1.0, "uniformly spaced"),
        (np.arange(10.0), np.zeros(10), -1.0, "stroke"),
    ],
)
def test_bad_inputs_are_named(times, error, stroke, words):
    with pytest.raises(ValueError, match=words):
        jh.error_spectrum(times, error, stroke=stroke)
