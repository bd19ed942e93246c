"""The demo record: the paper's u2 drive on a paper-like stage, two effects
concealed, the same everywhere."""

import jax
from jaxtyping import PRNGKeyArray

from .._signals import RaisedCosine, sample
from ._cases import ConcealedCase, _concealed_case


_DEMO_SEED = 2024


def demo_recording(*, key: PRNGKeyArray | None = None) -> ConcealedCase:
    """The demo record: a paper-like piezo stage under the paper's u2 = 4 - 4 cos(0.2
    pi t), scaled to volts (x12.5: 0..100 V), three periods (30 s) at 1 kHz, whose
    data conceal an asymmetry (8 sigma) and an input bias (6 sigma) under white sensor
    noise. `key=None` uses the bundled default seed, `jax.random.key(2024)`, so the
    demo is the same everywhere; pass a key for another draw.
    """
    if key is None:
        key = jax.random.key(_DEMO_SEED)
    signal = RaisedCosine(4.0 * 12.5, 0.1, duration=30.0)
    path = sample(signal, 1000.0)
    return _concealed_case(
        path,
        ("asymmetry", "input_bias"),
        key,
        "white",
        {"asymmetry": 8.0, "input_bias": 6.0},
        "demo-u2",
        "demo_recording",
    )
