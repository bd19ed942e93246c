import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import lowered_while

import jaxhyst as jh


Y = np.array([1.0, 2.0, 3.0, 4.0])
YHAT = np.array([1.0, 2.0, 3.0, 2.0])


def test_hand_computed_values():
    # errors [0, 0, 0, 2]; y_max = 4
    assert float(jh.metrics.rmse(Y, YHAT)) == pytest.approx(1.0)
    assert float(jh.metrics.mad(Y, YHAT)) == pytest.approx(2.0)
    assert float(jh.metrics.mrd(Y, YHAT)) == pytest.approx(50.0)
    assert float(jh.metrics.mae(Y, YHAT)) == pytest.approx(0.5)
    assert float(jh.metrics.nrmsd(Y, YHAT)) == pytest.approx(0.25)


def test_second_hand_computed_example():
    y = np.array([-2.0, 1.0, 0.5])
    yhat = np.array([-1.0, 1.5, 0.5])  # errors [1, 0.5, 0]; y_max = 2
    assert float(jh.metrics.rmse(y, yhat)) == pytest.approx(np.sqrt(1.25 / 3))
    assert float(jh.metrics.mad(y, yhat)) == pytest.approx(1.0)
    assert float(jh.metrics.mrd(y, yhat)) == pytest.approx(50.0)
    assert float(jh.metrics.mae(y, yhat)) == pytest.approx(0.5)
    assert float(jh.metrics.nrmsd(y, yhat)) == pytest.approx(np.sqrt(1.25 / 3) / 2)


def test_normalisation_uses_measured_output():
    # Scaling the model output must not change y_max.
    y = np.array([1.0, -1.0])
    assert float(jh.metrics.mrd(y, 10 * y)) == pytest.approx(900.0)
    assert float(jh.metrics.mrd(10 * y, y)) == pytest.approx(90.0)


def test_error_metrics_returns_python_floats():
    metrics = jh.error_metrics(Y, YHAT)
    assert list(metrics) == ["rmse", "mad", "mrd", "mae", "nrmsd"]
    assert all(type(v) is float for v in metrics.values())
    assert metrics == pytest.approx(
        {"rmse": 1.0, "mad": 2.0, "mrd": 50.0, "mae": 0.5, "nrmsd": 0.25}
    )


def test_integer_inputs_are_promoted():
    assert float(jh.metrics.mae([1, 2], [2, 2])) == pytest.approx(0.5)


@pytest.mark.parametrize(
    "fn",
    [jh.metrics.rmse, jh.metrics.mad, jh.metrics.mrd, jh.metrics.mae, jh.metrics.nrmsd],
)
def test_shape_mismatch(fn):
    with pytest.raises(ValueError, match=r"\(4,\) and \(3,\)"):
        fn(Y, YHAT[:3])


def test_shape_mismatch_error_metrics():
    with pytest.raises(ValueError, match="same shape"):
        jh.error_metrics(Y, YHAT[:, None])


def test_empty():
    with pytest.raises(ValueError, match="empty"):
        jh.metrics.rmse(np.zeros(0), np.zeros(0))


def test_jit_and_grad():
    y = jnp.asarray(Y)
    value = jax.jit(jh.metrics.rmse)(y, jnp.asarray(YHAT))
    assert float(value) == pytest.approx(1.0)
    # d rmse / d yhat = (yhat - y) / (N * rmse)
    grad = jax.grad(lambda yh: jh.metrics.rmse(y, yh))(jnp.asarray(YHAT))
    np.testing.assert_allclose(grad, (YHAT - Y) / (4 * 1.0))
    grad_mae = jax.grad(lambda yh: jh.metrics.mae(y, yh))(jnp.asarray(YHAT) + 0.1)
    np.testing.assert_allclose(grad_mae, np.full(4, 0.25) * np.sign(YHAT + 0.1 - Y))


def test_error_metrics_match_the_measures_without_compiling():
    y = np.sin(np.linspace(0, 7, 1001))
    yhat = y + 1e-3 * np.cos(np.linspace(0, 50, 1001))
    on_device = jax.block_until_ready(jnp.asarray(yhat))
    metrics, lowered = lowered_while(lambda: jh.error_metrics(y, on_device))
    # Host arithmetic: a report's metrics compile nothing.
    assert lowered == []
    for name, fn in zip(
        metrics,
        [
            jh.metrics.rmse,
            jh.metrics.mad,
            jh.metrics.mrd,
            jh.metrics.mae,
            jh.metrics.nrmsd,
        ],
    ):
        assert metrics[name] == pytest.approx(float(fn(y, yhat)), rel=1e-13), name


def test_error_metrics_keep_the_input_precision():
    y32, yhat32 = Y.astype(np.float32), YHAT.astype(np.float32) + 1e-4
    metrics = jh.error_metrics(y32, yhat32)
    assert metrics["mae"] == float(np.mean(np.abs(y32 - yhat32)))


def test_error_metrics_of_an_all_zero_measurement_are_inf_or_nan():
    metrics = jh.error_metrics(np.zeros(3), np.ones(3))
    assert metrics["mae"] == 1.0
    assert np.isinf(metrics["mrd"]) and np.isinf(metrics["nrmsd"])
