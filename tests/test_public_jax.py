"""jaxhyst uses public JAX only, and its compile caching lives at the edge.

A JAX release may rename anything private (`jax._src`, jaxlib's modules, XLA's
error texts); a library that reaches into them breaks on the next upgrade. The
persistent compilation cache is an application concern: the command line and the
demo turn it on (`jaxhyst._cache`), the numerical code never imports it.
"""

import re
from pathlib import Path


PACKAGE = Path(__file__).resolve().parent.parent / "jaxhyst"
PRIVATE = re.compile(
    r"jax\._src|jaxlib\.(lapack|_jax|xla_client|xla_extension|mlir)"
    r"|serialize_executable|xla_bridge|jax\.interpreters"
)
# Modules allowed to import the cache: the CLI, and the package's namespace.
CACHE_USERS = ("_cli", "__init__.py")
# The command line's store of exported programs: the one module that exports.
PROGRAM_STORE = "_cli/_programs.py"


def _sources():
    return sorted(PACKAGE.rglob("*.py"))


def _lines_matching(pattern: re.Pattern, *, besides: str = "") -> list[str]:
    return [
        f"{path.relative_to(PACKAGE)}:{number}: {line.strip()}"
        for path in _sources()
        if str(path.relative_to(PACKAGE)) != besides
        for number, line in enumerate(path.read_text().splitlines(), 1)
        if pattern.search(line)
    ]


def test_no_private_jax_anywhere_in_the_package():
    found = _lines_matching(PRIVATE)
    assert not found, "\n".join(found)


def test_the_numerical_code_does_not_import_the_compilation_cache():
    importers = [
        str(path.relative_to(PACKAGE))
        for path in _sources()
        if re.search(r"from \.+_cache import|import jaxhyst\._cache", path.read_text())
        and not str(path.relative_to(PACKAGE)).startswith(CACHE_USERS)
    ]
    assert importers == []


def test_the_library_jits_with_equinox_only():
    # No `jax.jit` with compiler options, no ahead-of-time lowering or compiling in
    # the package: `eqx.filter_jit` (and JAX's own transformations) only. The
    # command line's program store exports (public `jax.export`); nothing imports
    # it but the command line's entry point.
    pattern = re.compile(
        r"compiler_options|\)\.lower\(|\.compile\(\)|jax\.export|jax\.jit\("
    )
    found = _lines_matching(pattern, besides=PROGRAM_STORE)
    assert not found, "\n".join(found)
    importers = [
        str(path.relative_to(PACKAGE))
        for path in _sources()
        if re.search(r"_programs import", path.read_text())
    ]
    assert importers == ["_cli/_main.py"]
