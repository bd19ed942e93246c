"""A store of exported programs for the command line: a later `jaxhyst` process
loads a program it ran before instead of tracing and lowering it again.

JAX's persistent compilation cache (`jaxhyst._cache`) skips compiling, but every
process still traces each program and lowers it to find the cache entry: 1.6 s of a
2.9 s warm `jaxhyst fit` (benchmarks/HISTORY.md, session 37). This store keys a
program by what determines it before it is traced (the function's name, the static
part of its arguments, its arrays' shapes and dtypes, the versions of jaxhyst's
source and of its dependencies) and keeps it as `jax.export` serialized it.

It is an application concern, the CLI's alone: `install_program_store` replaces the
library's module-level `eqx.filter_jit` programs, for the rest of the process, by
wrappers that look the program up first; the numerical code neither imports nor
knows this module. Anything the key cannot describe for certain (a closure, an
object it does not know, a program with a host callback, which `jax.export` cannot
serialize) runs through the plain program, so the store can only skip work, never
change a result: a stored program is the very StableHLO the plain one lowers to.
"""

import dataclasses
import functools
import hashlib
import importlib
import importlib.metadata
import os
import pickle
import sys
import tempfile
import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any

import equinox as eqx
import jax
import numpy as np
from jax.core import Tracer


# Distributions whose code is traced into jaxhyst's programs.
_TRACED_DISTRIBUTIONS = (
    "jax",
    "jaxlib",
    "equinox",
    "optimistix",
    "lineax",
    "optax",
    "diffrax",
    "numpy",
)
_FORMAT = "1"


class _Unkeyable(Exception):
    """An argument or output the store cannot describe for certain."""


def _named(value) -> str | None:
    """`module:qualname` when importing that name gives back `value` itself."""
    module = getattr(value, "__module__", None)
    qualname = getattr(value, "__qualname__", None)
    if not module or not qualname or "<" in qualname:
        return None
    named = f"{module}:{qualname}"
    try:
        return named if _import(named) is value else None
    except (ImportError, AttributeError):
        return None


def _describe(value, out: list[str]) -> None:
    """Append to `out` a description of `value` that two processes agree on exactly
    when `eqx.filter_jit` would trace it to the same program: arrays by shape and
    dtype, everything else by value."""
    if isinstance(value, (jax.Array, np.ndarray, np.generic)):
        weak = getattr(value, "weak_type", False)
        out.append(f"a{value.shape}{value.dtype}{'w' if weak else ''}")
    elif value is None or isinstance(value, (bool, int, float, complex, str, bytes)):
        out.append(f"{type(value).__name__}:{value!r}")
    elif isinstance(value, (tuple, list)):
        out.append(f"{type(value).__name__}{len(value)}(")
        for item in value:
            _describe(item, out)
        out.append(")")
    elif isinstance(value, dict):
        out.append(f"dict{len(value)}(")
        for key in sorted(value, key=repr):
            _describe(key, out)
            _describe(value[key], out)
        out.append(")")
    elif isinstance(value, frozenset):
        items = []
        for item in value:
            part = []
            _describe(item, part)
            items.append("".join(part))
        out.append("frozenset(" + ",".join(sorted(items)) + ")")
    elif isinstance(value, eqx.Module) and (named := _named(value)) is not None:
        # A module-level object by its name: a function under `eqx.filter_jit`.
        out.append(f"n:{named}")
    elif isinstance(value, eqx.Module):
        named = _named(type(value))
        if named is None:
            raise _Unkeyable(type(value).__qualname__)
        out.append(f"m:{named}(")
        for field in dataclasses.fields(value):
            out.append(field.name + "=")
            _describe(getattr(value, field.name, None), out)
        out.append(")")
    elif isinstance(value, functools.partial):
        out.append("partial(")
        _describe((value.func, value.args, value.keywords), out)
        out.append(")")
    elif isinstance(value, np.dtype):
        out.append(f"dtype:{value}")
    else:
        # Functions, classes, enumerations and other objects importable by name.
        named = _named(value)
        if named is None:
            raise _Unkeyable(type(value).__qualname__)
        out.append(f"n:{named}")


def _structure(value, leaves: list) -> tuple:
    """`value` as a picklable recipe with its arrays moved to `leaves`."""
    if isinstance(value, (jax.Array, np.ndarray, np.generic)):
        leaves.append(value)
        return ("leaf",)
    if value is None or isinstance(value, (bool, int, float, complex, str, bytes)):
        return ("value", value)
    if isinstance(value, (tuple, list)):
        kind = "tuple" if isinstance(value, tuple) else "list"
        if isinstance(value, tuple) and type(value) is not tuple:
            raise _Unkeyable(type(value).__qualname__)
        return (kind, tuple(_structure(item, leaves) for item in value))
    if isinstance(value, dict) and type(value) is dict:
        return ("dict", tuple((k, _structure(v, leaves)) for k, v in value.items()))
    if isinstance(value, frozenset) and all(
        v is None or isinstance(v, (bool, int, float, str)) for v in value
    ):
        return ("value", value)
    if isinstance(value, eqx.Module):
        named = _named(type(value))
        if named is None:
            raise _Unkeyable(type(value).__qualname__)
        fields = tuple(
            (field.name, _structure(getattr(value, field.name), leaves))
            for field in dataclasses.fields(value)
        )
        return ("module", named, fields)
    named = _named(value)
    if named is None:
        raise _Unkeyable(type(value).__qualname__)
    return ("named", named)


def _import(named: str) -> Any:
    module, qualname = named.split(":")
    found: Any = importlib.import_module(module)
    for part in qualname.split("."):
        found = getattr(found, part)
    return found


def _rebuild(recipe: tuple, leaves) -> object:
    """The value `_structure` described, its arrays taken in order from `leaves`."""
    kind = recipe[0]
    if kind == "leaf":
        return next(leaves)
    if kind == "value":
        return recipe[1]
    if kind in ("tuple", "list"):
        items = [_rebuild(item, leaves) for item in recipe[1]]
        return tuple(items) if kind == "tuple" else items
    if kind == "dict":
        return {key: _rebuild(item, leaves) for key, item in recipe[1]}
    if kind == "module":
        # As equinox unflattens a module: its fields set, no `__init__` run.
        module = object.__new__(_import(recipe[1]))
        for name, item in recipe[2]:
            object.__setattr__(module, name, _rebuild(item, leaves))
        return module
    return _import(recipe[1])


def _fingerprint() -> str:
    """jaxhyst's source and the versions of what it traces, as one digest."""
    digest = hashlib.sha256(_FORMAT.encode())
    for name in _TRACED_DISTRIBUTIONS:
        try:
            version = importlib.metadata.version(name)
        except importlib.metadata.PackageNotFoundError:
            version = "-"
        digest.update(f"{name}={version};".encode())
    package = Path(__file__).resolve().parent.parent
    for path in sorted(package.rglob("*.py")):
        digest.update(str(path.relative_to(package)).encode())
        digest.update(path.read_bytes())
    digest.update(os.environ.get("EQX_ON_ERROR", "").encode())
    return digest.hexdigest()


# JAX options that do not change a traced program: caching, logging, compiling
# (the compilation cache keys compile options itself).
_NOT_TRACING = ("cache", "log", "explain", "compil", "traceback")


def _tracing_options() -> str:
    """JAX's configuration options that may change what a program traces to (the
    default matmul precision, rank promotion, ...), as one string."""
    values = jax.config.values
    return ";".join(
        f"{name}={values[name]!r}"
        for name in sorted(values)
        if not any(word in name for word in _NOT_TRACING)
    )


class _Store:
    """The folder of exported programs and the programs loaded in this process."""

    def __init__(self, folder: Path):
        self.folder = folder
        self.fingerprint = _fingerprint()
        self.loaded: dict[str, tuple[Callable, tuple] | None] = {}
        # The entries by the in-process form of their arguments (see `_stored`).
        self.seen: dict[tuple, tuple[Callable, tuple] | None] = {}
        self.lock = threading.Lock()

    def key(self, name: str, args, kwargs) -> str:
        parts = [
            self.fingerprint,
            name,
            jax.default_backend(),
            str(jax.dtypes.canonicalize_dtype(np.float64)),  # x64 on or off
            _tracing_options(),
        ]
        _describe((args, kwargs), parts)
        return hashlib.sha256("\x1f".join(parts).encode()).hexdigest()[:40]

    def _read(self, path: Path):
        try:
            program, recipe = pickle.loads(path.read_bytes())
            return _loaded(program), recipe
        except Exception:  # noqa: BLE001 (an entry cut short, or foreign: export again)
            return None

    def _write(self, path: Path, data: bytes) -> None:
        try:
            fd, temporary = tempfile.mkstemp(dir=self.folder, prefix=".partial-")
            with os.fdopen(fd, "wb") as file:
                file.write(data)
            os.replace(temporary, path)
        except OSError:
            pass  # a store that cannot be written only costs the next process time

    def program(self, name: str, function, key: str, leaves, treedef, static):
        """The runner of `function`'s program for these arguments (loaded, or
        exported now and stored) and the recipe of its output; None where the
        program cannot be exported (then, and in later processes, the plain
        program runs)."""
        with self.lock:
            if key in self.loaded:
                return self.loaded[key]
        path = self.folder / f"{name}-{key}.jaxexport"
        refused = path.with_suffix(".refused")
        found = None
        if path.exists():
            found = self._read(path)
        if found is None and not refused.exists():
            found = _export(function, leaves, treedef, static)
            if found is None:
                self._write(refused, b"")
            else:
                exported, recipe = found
                serialized = bytes(exported.serialize())
                self._write(path, pickle.dumps((serialized, recipe)))
                # Run what later processes load: a deserialized program lowers to
                # another module than the exported object does, and a second process
                # would compile it again (measured: 9 of a diagnosis's 168 programs,
                # 64 s of its 96 s), its compiled program not in the cache yet.
                found = (_loaded(serialized), recipe)
        entry = None
        if found is not None:
            exported, recipe = found
            entry = (jax.jit(exported.call), recipe)
        with self.lock:
            self.loaded[key] = entry
        return entry


def _loaded(serialized: bytes) -> jax.export.Exported:
    """An exported program from its bytes, as every process that runs it loads it."""
    return jax.export.deserialize(bytearray(serialized))


# XLA:CPU's LAPACK kernels, which `jax.export` declines to serialize by default
# because their ABI may change between jaxlib releases: the store keys every program
# by the exact jaxlib version, so a stored program only ever runs on the jaxlib that
# exported it. Host callbacks (`eqx.error_if`, `jax.debug`) are never among them:
# they point into the exporting process.
_KERNELS = ("geqrf", "orgqr", "ungqr", "ormqr", "unmqr", "gesdd", "gesvd", "syevd")
_KERNELS += ("heevd", "getrf", "potrf", "trsm", "geev", "gees", "gehrd", "sytrd")
_KERNELS += ("hetrd", "tridiagonal", "tridiagonal_solve", "gtsv")
_SAME_JAXLIB_ONLY = tuple(
    jax.export.DisabledSafetyCheck.custom_call(f"lapack_{kind}{kernel}_ffi")
    for kind in "sdcz"
    for kernel in _KERNELS
)


def _export(function, leaves, treedef, static):
    """`function` at these arguments exported (`jax.export`), with the recipe of its
    output; None where that fails: a host callback, another custom call, an output
    the recipe cannot hold, or an error, which the plain program then raises."""
    recipes = []

    def flat(*arrays):
        args, kwargs = eqx.combine(jax.tree.unflatten(treedef, arrays), static)
        out_leaves = []
        recipes.append(_structure(function(*args, **kwargs), out_leaves))
        return out_leaves

    shapes = [
        jax.ShapeDtypeStruct(
            leaf.shape, leaf.dtype, weak_type=getattr(leaf, "weak_type", False)
        )
        for leaf in leaves
    ]
    try:
        exported = jax.export.export(jax.jit(flat), disabled_checks=_SAME_JAXLIB_ONLY)(
            *shapes
        )
        pickle.dumps(recipes[0])
    except Exception:  # noqa: BLE001
        return None
    return exported, recipes[0]


def _stored(store: _Store, name: str, program):
    """`program` (an `eqx.filter_jit` function) looked up in `store` first."""
    function = program.__wrapped__

    @functools.wraps(function)
    def run(*args, **kwargs):
        dynamic, static = eqx.partition((args, kwargs), eqx.is_array)
        leaves, treedef = jax.tree.flatten(dynamic)
        if any(isinstance(leaf, Tracer) for leaf in leaves):
            return program(*args, **kwargs)  # called inside another program
        # In this process, the arguments as `eqx.filter_jit` itself tells its
        # programs apart (the static part by equality, the arrays by shape and
        # dtype) name the program already looked up; the durable key is only
        # described for a new one.
        static_leaves, static_def = jax.tree.flatten(static)
        shapes = tuple(
            (leaf.shape, leaf.dtype, getattr(leaf, "weak_type", False))
            for leaf in leaves
        )
        try:
            seen = (name, treedef, static_def, tuple(static_leaves), shapes)
            entry = store.seen.get(seen, _NEW)
        except TypeError:  # an unhashable static leaf
            seen, entry = None, _NEW
        if entry is _NEW:
            try:
                key = store.key(name, args, kwargs)
            except _Unkeyable:
                entry = None
            else:
                entry = store.program(name, function, key, leaves, treedef, static)
            if seen is not None:
                store.seen[seen] = entry
        if not isinstance(entry, tuple):
            return program(*args, **kwargs)
        runner, recipe = entry
        return _rebuild(recipe, iter(runner(*leaves)))

    return run


_NEW = object()
_JIT_TYPE: type = type(eqx.filter_jit(lambda: None))
_installed = False


def install_program_store(folder: Path) -> None:
    """Look every module-level `eqx.filter_jit` program of jaxhyst up in `folder`
    (created if missing) before tracing it, for the rest of this process (a second
    call changes nothing)."""
    global _installed
    if _installed:
        return
    folder.mkdir(mode=0o700, parents=True, exist_ok=True)
    store = _Store(folder)
    _installed = True
    wrapped: dict[int, Callable] = {}
    for module_name, module in list(sys.modules.items()):
        if module_name.split(".")[0] != "jaxhyst" or module is None:
            continue
        for attribute, value in list(vars(module).items()):
            if not isinstance(value, _JIT_TYPE):
                continue
            if id(value) not in wrapped:
                name = f"{module_name}.{attribute}"
                wrapped[id(value)] = _stored(store, name, value)
            setattr(module, attribute, wrapped[id(value)])
