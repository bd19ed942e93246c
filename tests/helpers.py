"""Shared test fixtures: the paper's input on a uniform grid, and typical parameters."""

import numpy as np

import jaxhyst as jh


def paper_u1_path(rate: float = 1000.0, periods: int = 1) -> jh.InputPath:
    t = np.arange(int(round(10.0 * periods * rate)) + 1) / rate
    return jh.InputPath.from_samples(t, 2 - 2 * np.cos(0.2 * np.pi * t))


def multisine_path(rate: float = 1000.0, duration: float = 4.0) -> jh.InputPath:
    t = np.arange(int(round(duration * rate)) + 1) / rate
    u = (
        1.0 * np.sin(2 * np.pi * 0.5 * t)
        + 0.5 * np.sin(2 * np.pi * 1.7 * t + 0.3)
        + 0.25 * np.sin(2 * np.pi * 4.1 * t + 1.1)
    )
    return jh.InputPath.from_samples(t, u)


def piezo_model(**overrides) -> jh.PiezoBoucWen:
    values = dict(k1=0.3, k2=1.0, A1=0.5, beta1=0.6, gamma1=0.2, n=1.5)
    values.update(overrides)
    return jh.PiezoBoucWen(**values)
