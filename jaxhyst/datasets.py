"""Loaders for the real data sets used by the examples, tests and benchmarks.

The data are not shipped with the package: each loader reads its files from
`data_dir` (default `default_data_dir()`, which honours the `JAXHYST_DATA_DIR`
environment variable) and says where to get them when they are missing. A piezo
actuator (`load_piezo_actuator`), the Bouc-Wen benchmark (`load_bouc_wen_benchmark`,
a `BoucWenBenchmark`), structural cyclic tests (`load_structural_test`, the tests in
`STRUCTURAL_TESTS`) and MR dampers (`load_mr_damper` over `MR_DAMPER_TESTS`,
`load_mr_damper_sine`); each gives `jaxhyst.Recording`s.
"""

from ._datasets import (
    MR_DAMPER_TESTS as MR_DAMPER_TESTS,
    STRUCTURAL_TESTS as STRUCTURAL_TESTS,
    BoucWenBenchmark as BoucWenBenchmark,
    default_data_dir as default_data_dir,
    load_bouc_wen_benchmark as load_bouc_wen_benchmark,
    load_mr_damper as load_mr_damper,
    load_mr_damper_sine as load_mr_damper_sine,
    load_piezo_actuator as load_piezo_actuator,
    load_structural_test as load_structural_test,
)


__all__ = [
    "MR_DAMPER_TESTS",
    "STRUCTURAL_TESTS",
    "BoucWenBenchmark",
    "default_data_dir",
    "load_bouc_wen_benchmark",
    "load_mr_damper",
    "load_mr_damper_sine",
    "load_piezo_actuator",
    "load_structural_test",
]
