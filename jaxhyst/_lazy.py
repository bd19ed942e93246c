"""Package exports imported when first used (PEP 562), listed once.

A package's `__init__.py` lists its public names as ordinary imports inside an
`if TYPE_CHECKING:` block, which type checkers and editors read as they are, and
ends with `__getattr__, __dir__, __all__ = lazy_exports(__name__, __file__)`.
`lazy_exports` reads that block from the file's source (once, at import) to learn
which module defines each name; the first `package.name` imports that module and
keeps the value on the package. `import jaxhyst` thus loads no model, solver or
diagnosis code, and a command pays only for the modules it uses: the diagnosis's
hundred-odd `eqx.Module` classes take about 0.1 s to create on the 2-core machine,
the synthetic recordings and optax another 0.1 s.
"""

import ast
import importlib
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any


def _listed(init_file: str) -> dict[str, tuple[str, str | None]]:
    """Each name the `if TYPE_CHECKING:` block of `init_file` imports, with the
    relative module it comes from and the attribute (None: the name is a
    submodule, `from . import synthetic`)."""
    tree = ast.parse(Path(init_file).read_text(encoding="utf-8"), init_file)
    exports: dict[str, tuple[str, str | None]] = {}
    for node in tree.body:
        if not (isinstance(node, ast.If) and ast.unparse(node.test) == "TYPE_CHECKING"):
            continue
        for statement in node.body:
            if not (isinstance(statement, ast.ImportFrom) and statement.level == 1):
                raise ValueError(
                    f"{init_file}:{statement.lineno}: the TYPE_CHECKING block may "
                    "hold only relative imports ('from .module import name as "
                    "name'), which it lists as the package's exports"
                )
            for alias in statement.names:
                name = alias.asname or alias.name
                if statement.module is None:
                    exports[name] = (f".{alias.name}", None)
                else:
                    exports[name] = (f".{statement.module}", alias.name)
    return exports


def lazy_exports(
    package: str,
    init_file: str,
    *,
    computed: dict[str, Callable[[], Any]] | None = None,
) -> tuple[Callable[[str], Any], Callable[[], list[str]], list[str]]:
    """`__getattr__`, `__dir__` and `__all__` for `package`, whose `__init__.py`
    is `init_file`: the names its `if TYPE_CHECKING:` block imports, each imported
    from its module when first asked for; `computed` names (such as
    `__version__`, not in `__all__`) are the value of their function, called when
    first asked for."""
    exports = _listed(init_file)
    computed = dict(computed or {})

    def __getattr__(name: str) -> Any:
        if name in computed:
            value = computed[name]()
            setattr(sys.modules[package], name, value)
            return value
        try:
            module, attribute = exports[name]
        except KeyError:
            raise AttributeError(
                f"module {package!r} has no attribute {name!r}"
            ) from None
        value = importlib.import_module(module, package)
        if attribute is not None:
            value = getattr(value, attribute)
        setattr(sys.modules[package], name, value)  # later lookups find it at once
        return value

    def __dir__() -> list[str]:
        return sorted(set(exports) | set(vars(sys.modules[package])))

    return __getattr__, __dir__, sorted(exports)
