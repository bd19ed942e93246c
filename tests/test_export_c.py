"""The C export matches `simulate` and `compensate` (compiled with the system C
compiler when there is one)."""

import ctypes
import shutil
import subprocess

import numpy as np
import pytest

import jaxhyst as jh


PAPER = jh.PiezoBoucWen.paper_table4(3)
CC = shutil.which("cc") or shutil.which("gcc") or shutil.which("clang")
needs_cc = pytest.mark.skipif(CC is None, reason="no C compiler (cc/gcc/clang) found")
TOLERANCE = 1e-9  # of the output's range: the stated agreement with `simulate`


def _rich_input(rate=1000.0):
    """A slow 0-4 V cycle, then a chirp from 0.2 to 20 Hz, then decaying cycles:
    minor loops, reversals at every amplitude, rates over two decades."""
    dt = 1.0 / rate
    slow = np.arange(0.0, 10.0, dt)
    fast = np.arange(0.0, 4.0, dt)
    decay = np.arange(0.0, 4.0, dt)
    phase = 2 * np.pi * (0.2 * fast + (20.0 - 0.2) * fast**2 / (2 * 4.0))
    u = np.concatenate(
        [
            2 - 2 * np.cos(2 * np.pi * 0.1 * slow),
            2 - 2 * np.cos(phase),
            2 - 2 * np.exp(-decay / 1.5) * np.cos(2 * np.pi * 2.0 * decay),
        ]
    )
    return jh.InputPath(0.0, dt, u)


def _library(model, tmp_path, **options):
    header, source = jh.export_c(model, tmp_path, prefix="m", **options)
    library = tmp_path / "libm.so"
    subprocess.run(
        [
            CC,
            "-std=c99",
            "-O2",
            "-shared",
            "-fPIC",
            str(source),
            "-o",
            str(library),
            "-lm",
        ],
        check=True,
        capture_output=True,
    )
    lib = ctypes.CDLL(str(library))
    lib.m_step.restype = ctypes.c_double
    lib.m_step.argtypes = [ctypes.c_void_p, ctypes.c_double, ctypes.c_double]
    lib.m_output.restype = ctypes.c_double
    lib.m_compensate_step.restype = ctypes.c_double
    lib.m_compensate_step.argtypes = [
        ctypes.c_void_p,
        ctypes.c_double,
        ctypes.c_double,
        ctypes.c_double,
        ctypes.c_double,
        ctypes.POINTER(ctypes.c_int),
    ]
    lib.m_init.argtypes = [ctypes.c_void_p, ctypes.c_double]
    return lib, header


def _simulate_c(lib, u, dt):
    state = (ctypes.c_double * 2)()
    lib.m_init(state, u[0])
    out = [lib.m_output(state)]
    for value in u[1:]:
        out.append(lib.m_step(state, float(value), dt))
    return np.asarray(out)


@needs_cc
@pytest.mark.parametrize(
    "model, substeps",
    [
        (PAPER, 1),
        (jh.CorrectedPiezoBoucWen.from_piezo(PAPER, eps=3e-7), 2),
        (PAPER.replace(n=1.7), 1),
        (jh.PiezoBoucWen(*PAPER.parameters().values(), smoothing=jh.TanhSign(1e-6)), 1),
    ],
    ids=["paper", "corrected", "n1.7", "tanh"],
)
def test_c_model_matches_simulate(model, substeps, tmp_path):
    path = _rich_input()
    lib, header = _library(model, tmp_path, substeps=substeps)
    assert "m_compensate_step" in header.read_text()
    expected = np.asarray(jh.simulate(model, path, jh.RK4(substeps=substeps)))
    got = _simulate_c(lib, np.asarray(path.values), float(path.dt))
    np.testing.assert_allclose(got, expected, rtol=0, atol=TOLERANCE * np.ptp(expected))


@needs_cc
def test_c_compensator_matches_compensate(tmp_path):
    path = _rich_input(500.0)
    reference = 1.05 * np.asarray(jh.simulate(PAPER, path))  # a little out of reach
    result = jh.compensate(PAPER, np.asarray(path.times), reference, limits=(0.0, 4.0))
    lib, _ = _library(PAPER, tmp_path)
    state = (ctypes.c_double * 2)()
    drive = np.asarray(result.drive)
    lib.m_init(state, float(drive[0]))
    flag = ctypes.c_int()
    got, limited = [drive[0]], [bool(result.at_limit[0])]
    for target in reference[1:]:
        got.append(
            lib.m_compensate_step(
                state, float(target), float(path.dt), 0.0, 4.0, ctypes.byref(flag)
            )
        )
        limited.append(bool(flag.value))
    np.testing.assert_allclose(got, drive, rtol=0, atol=1e-9 * 4.0)
    assert limited == list(np.asarray(result.at_limit))


def test_export_c_refuses_what_it_cannot_write(tmp_path):
    with pytest.raises(ValueError, match="phi = 0.01"):
        jh.export_c(jh.CorrectedPiezoBoucWen.from_piezo(PAPER, phi=0.01), tmp_path)
    stage = jh.PiezoStage.from_piezo(PAPER, natural_frequency=100.0, damping_ratio=0.5)
    with pytest.raises(ValueError, match="PiezoStage has no C export"):
        jh.export_c(stage, tmp_path)
    with pytest.raises(ValueError, match="C identifier"):
        jh.export_c(PAPER, tmp_path, prefix="9lives")
    jh.export_c(PAPER, tmp_path)
    before = (tmp_path / "jaxhyst_model.c").read_text()
    with pytest.raises(FileExistsError, match="overwrite=True"):
        jh.export_c(PAPER.replace(k1=1.0), tmp_path)
    assert (tmp_path / "jaxhyst_model.c").read_text() == before
    jh.export_c(PAPER.replace(k1=1.0), tmp_path, overwrite=True)
    assert (tmp_path / "jaxhyst_model.c").read_text() != before
