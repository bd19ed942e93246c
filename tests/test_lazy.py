"""The package's exports are imported when first used: `import jaxhyst` loads no
model or diagnosis code, a command imports only its own, and every export still
resolves to its module's object."""

import importlib
import json
import subprocess
import sys
import textwrap

import pytest

import jaxhyst as jh
from jaxhyst import _lazy


def _modules_after(code: str) -> list[str]:
    """The modules a fresh interpreter holds after running `code`."""
    script = code + "\nimport json, sys; print(json.dumps(sorted(sys.modules)))"
    result = subprocess.run(
        [sys.executable, "-c", textwrap.dedent(script)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.returncode == 0, result.stderr
    return json.loads(result.stdout.strip().splitlines()[-1])


def test_importing_the_package_loads_none_of_its_modules():
    loaded = _modules_after("import jaxhyst")
    assert "jax" not in loaded
    assert [m for m in loaded if m.startswith("jaxhyst.")] == ["jaxhyst._lazy"]


def test_the_fit_command_imports_neither_the_diagnosis_nor_the_synthetic_records():
    loaded = _modules_after(
        "from jaxhyst._cli._main import build_parser\n"
        "build_parser(['fit', 'recording.csv'])"
    )
    assert "jaxhyst._cli._fit" in loaded
    for heavy in (
        "jaxhyst._diagnose._families",
        "jaxhyst._diagnose._diagnose",
        "jaxhyst.synthetic",
        "jaxhyst._compensate",
        "jaxhyst._cli._diagnose",
        "optax",
    ):
        assert heavy not in loaded, heavy


@pytest.mark.parametrize("package", [jh, importlib.import_module("jaxhyst._report")])
def test_every_export_resolves_to_the_object_its_module_defines(package):
    listed = _lazy._listed(package.__file__)
    assert sorted(listed) == package.__all__
    for name, (module, attribute) in listed.items():
        expected = importlib.import_module(module, package.__name__)
        if attribute is not None:
            expected = getattr(expected, attribute)
        assert getattr(package, name) is expected, name
    assert set(package.__all__) <= set(dir(package))
    with pytest.raises(AttributeError, match="has no attribute 'no_such_name'"):
        package.no_such_name  # noqa: B018


def test_the_version_is_read_when_asked_for():
    assert isinstance(jh.__version__, str) and jh.__version__
    assert "__version__" not in jh.__all__


def test_a_type_checking_block_with_anything_but_relative_imports_is_refused(
    tmp_path,
):
    init = tmp_path / "__init__.py"
    init.write_text(
        "from typing import TYPE_CHECKING\n"
        "if TYPE_CHECKING:\n"
        "    from ._a import b as b\n"
        "    import numpy\n"
    )
    with pytest.raises(ValueError, match=r"__init__.py:4: the TYPE_CHECKING block"):
        _lazy._listed(str(init))
