"""Traced programs kept on disk, so that a later process skips tracing them.

JAX's persistent compilation cache (`enable_compilation_cache`) saves compiling, but
every process still traces and lowers each program before it can look the compiled
one up, and on the 2-core machine that is most of a warm `jaxhyst fit` and half a
warm diagnosis. `stored_jit` is `eqx.filter_jit` plus a store: when the store is on
(`enable_compilation_cache` turns it on with the compilation cache, in a
`programs` folder inside it), the first call with a given structure of arguments
traces the function, exports it (`jax.export`) and writes the exported program to
the store; a later call with the same structure, in this process or another, reads
it back and runs it without tracing. The export is what runs in both cases, so a
warm run computes with the same program as the cold run that wrote it.

Beside each program the store keeps its compiled executable (`.executable`,
`jax.experimental.serialize_executable`), keyed further by the XLA flags, the
compiler options and the host processor's model and features (XLA:CPU compiles for
the processor it runs on): a later process on the same machine loads it as it is,
skipping the lowering and the compilation-cache lookup as well. JAX's compilation
cache does not keep a second copy of these executables (writing it cost more than a
tenth of a second of a cold fit). Only an executable XLA compiled in this process is
kept: one that JAX's compilation cache handed back (an older jaxhyst wrote it there)
does not serialize faithfully on XLA:CPU (its kernels are missing when it runs), so
such a program is compiled through its export again by the next process instead.

A stored program is found by a key that fixes everything tracing depends on:
the function (module and qualified name), the shapes, dtypes and positions of the
array arguments, every other argument's value (numbers, strings, tuples, `eqx.Module`
instances field by field, functions and classes by name), the versions of Python,
jaxhyst's own source (a hash of its files), JAX, jaxlib, equinox, optimistix,
lineax, optax and NumPy, the backend and its devices, the JAX options that change
tracing, and the `EQX_*` environment variables. Where an argument is something the
key cannot pin down by value (an object of a class outside those packages, a
lambda or local function, a closure over arrays or over such objects, a
`functools.partial`), or the program calls back into Python
(`eqx.error_if`, `jax.debug.print`), or the call is itself being traced (inside
`jax.jit`, `jax.vmap`, `jax.grad`), the call runs as plain `eqx.filter_jit` and
nothing is stored.

`prepare` traces and compiles what a call would run without running it (store on or
off), so that a pipeline compiles its later stages in a background thread
(`preparing`) while an earlier one runs: `identify` compiles its polish and its
identifiability during the swarm. A call that arrives while another thread builds
its program waits for it instead of building it again.

`prefetching` loads executables ahead of the calls that need them: in a block, the
first stored program names a list (kept in the store, `prefetch/`) of the programs
the last block that began with it used, in order, and a background thread loads
them while the block computes (loading releases Python's lock). The CLI runs each
command in such a block, so a command run a second time finds most of its programs
loaded when it asks for them.

Files are written to a temporary name and renamed, so two processes sharing the
folder never read a half-written program; each file carries a checksum and its full
key, and one that does not match is traced again and written over. The store holds
pickled Python objects (the non-array parts of the outputs) and programs: like the
compilation cache, do not point it at a folder that others can write.
"""

import contextlib
import contextvars
import dataclasses
import enum
import functools
import hashlib
import importlib.metadata
import math
import os
import pickle
import platform
import re
import sys
import tempfile
import threading
import types
import weakref
import zlib
from collections.abc import Callable, Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path
from typing import Any, Generic, NamedTuple, ParamSpec, TypeVar

import equinox as eqx
import jax
import numpy as np
from jax._src import (
    config as _jax_config,  # a thread-local cache setting
    core as _jax_core,  # trace_state_clean: no public equivalent
)
from jax.core import Tracer
from jax.experimental import serialize_executable

from . import _xla_options


_P = ParamSpec("_P")
_R = TypeVar("_R")

_FORMAT = "jaxhyst-program-store 1"
_MAGIC = b"JAXHYST-PROGRAM 1\n"
# Packages whose functions, classes and modules may appear in a key by name: their
# code is pinned by the versions (or, for jaxhyst, the source hash) in the key.
_PINNED_PACKAGES = (
    "jax",
    "jaxlib",
    "equinox",
    "optimistix",
    "lineax",
    "optax",
    "numpy",
    "jaxhyst",
)
# JAX options that change what tracing produces.
_TRACE_OPTIONS = (
    "jax_enable_x64",
    "jax_default_matmul_precision",
    "jax_numpy_rank_promotion",
    "jax_numpy_dtype_promotion",
    "jax_default_prng_impl",
    "jax_enable_checks",
    "jax_debug_nans",
    "jax_debug_infs",
    "jax_threefry_partitionable",
)
# With these on, JAX's own behaviour (op-by-op re-runs, no compilation) is wanted.
_DEBUG_OPTIONS = ("jax_disable_jit", "jax_debug_nans", "jax_debug_infs")
_CUSTOM_CALL_REFUSED = "Cannot serialize code with custom calls"
_CALLBACKS_REFUSED = "serialization of host_callbacks"

_store: Path | None = None


def enable_program_store(path: Path | None) -> None:
    """Keep traced programs in `path` (created when the first one is written), or
    turn the store off with `None`. `enable_compilation_cache` calls this."""
    global _store
    _store = None if path is None else Path(path)


def program_store() -> Path | None:
    """The folder `stored_jit` programs are kept in, or `None` when the store is
    off (the default: a library import changes nothing)."""
    return _store


class _Unpinned(Exception):
    """An argument the key cannot pin down by value (internal: the call then runs
    unstored)."""


def _pinned_name(obj: Any) -> str:
    module = getattr(obj, "__module__", None)
    qualname = getattr(obj, "__qualname__", None)
    if not isinstance(module, str) or not isinstance(qualname, str):
        raise _Unpinned(type(obj).__name__)
    if module.split(".")[0] not in _PINNED_PACKAGES or "<" in qualname:
        raise _Unpinned(f"{module}.{qualname}")
    return f"{module}.{qualname}"


def _encode(obj: Any, *, static: bool = False) -> str:
    """A string that fixes `obj` for tracing: arrays by shape, dtype and weak type,
    everything else by value. Raises `_Unpinned` for what it cannot fix."""
    if eqx.is_array(obj):
        if static:
            raise _Unpinned("an array in a static field")
        weak = bool(getattr(obj, "weak_type", False))
        return f"A[{obj.dtype}{tuple(obj.shape)}{'w' if weak else ''}]"
    if obj is None or isinstance(obj, (bool, int, float, complex, str, bytes)):
        return f"{type(obj).__name__}:{obj!r}"
    if isinstance(obj, enum.Enum):
        return f"E[{_pinned_name(type(obj))}.{obj.name}]"
    if isinstance(obj, np.dtype):
        return f"D[{obj.str}]"
    if isinstance(obj, eqx.Module):
        parts = [
            f"{f.name}={_encode(getattr(obj, f.name), static=static or bool(f.metadata.get('static', False)))}"
            for f in dataclasses.fields(obj)
        ]
        return f"M[{_pinned_name(type(obj))}]({','.join(parts)})"
    if isinstance(obj, tuple) and hasattr(obj, "_fields"):  # a NamedTuple
        inner = ",".join(_encode(x, static=static) for x in obj)
        return f"N[{_pinned_name(type(obj))}]({inner})"
    if type(obj) in (tuple, list):
        inner = ",".join(_encode(x, static=static) for x in obj)
        return f"{type(obj).__name__}({inner})"
    if type(obj) is dict:
        items = sorted(
            (_encode(k, static=True), _encode(v, static=static)) for k, v in obj.items()
        )
        return "dict(" + ",".join(f"{k}:{v}" for k, v in items) + ")"
    if type(obj) in (set, frozenset):
        return f"{type(obj).__name__}({','.join(sorted(_encode(x, static=True) for x in obj))})"
    if isinstance(obj, type):
        return f"T[{_pinned_name(obj)}]"
    if isinstance(obj, types.FunctionType):
        # A decorated function's closure holds what it wraps: pinned by value too.
        cells = tuple(c.cell_contents for c in obj.__closure__ or ())
        fixed = (obj.__defaults__, obj.__kwdefaults__, cells)
        return f"F[{_pinned_name(obj)}]{_encode(fixed, static=True)}"
    if isinstance(obj, (types.BuiltinFunctionType, np.ufunc)):
        return f"F[{_pinned_name(obj)}]"
    if isinstance(obj, types.ModuleType):
        if obj.__name__.split(".")[0] not in _PINNED_PACKAGES:
            raise _Unpinned(obj.__name__)
        return f"Mod[{obj.__name__}]"
    # jax's jitted functions (jnp.sin and the like) carry their wrapped function.
    wrapped = getattr(obj, "__wrapped__", None)
    if wrapped is not None and callable(obj) and type(obj).__module__.startswith("jax"):
        return f"J[{_encode(wrapped, static=True)}]"
    raise _Unpinned(type(obj).__qualname__)


@functools.cache
def _source_hash() -> str:
    """A hash of jaxhyst's Python source: a changed file is a new key."""
    digest = hashlib.sha256()
    root = Path(__file__).resolve().parent
    for path in sorted(root.rglob("*.py")):
        digest.update(str(path.relative_to(root)).encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()


def _version(package: str) -> str:
    try:
        return importlib.metadata.version(package)
    except importlib.metadata.PackageNotFoundError:
        return "absent"


@functools.cache
def _fixed_environment() -> str:
    versions = [f"{p}={_version(p)}" for p in _PINNED_PACKAGES if p != "jaxhyst"]
    devices = jax.devices()
    return ";".join(
        [
            _FORMAT,
            f"python={sys.version_info[:3]}",
            f"jaxhyst-source={_source_hash()}",
            *versions,
            f"backend={jax.default_backend()}",
            f"devices={len(devices)}x{devices[0].device_kind}",
        ]
    )


@functools.cache
def _host_processor() -> str:
    """The CPU's model and features (XLA:CPU compiles for the host it runs on): a
    store shared by machines with different processors keeps one executable each."""
    try:
        lines = Path("/proc/cpuinfo").read_text().splitlines()
    except OSError:
        return f"{platform.machine()}:{platform.processor()}"
    wanted = ("model name", "flags", "Features", "CPU part")
    found = sorted({line for line in lines if line.split(":")[0].strip() in wanted})
    return hashlib.sha256("\n".join(found).encode()).hexdigest()


def _compile_environment() -> str:
    """What compiling depends on beyond the traced program: the XLA flags and the
    host processor."""
    return f"XLA_FLAGS={os.environ.get('XLA_FLAGS', '')!r};cpu={_host_processor()}"


def _environment() -> str:
    options = [f"{name}={getattr(jax.config, name, None)!r}" for name in _TRACE_OPTIONS]
    eqx_env = [
        f"{k}={v}" for k, v in sorted(os.environ.items()) if k.startswith("EQX_")
    ]
    return ";".join([_fixed_environment(), *options, *eqx_env])


class _Slot:
    """Where the `index`-th array output goes back into the output's structure."""

    def __init__(self, index: int):
        self.index = index


class _Program(NamedTuple):
    run: Any  # the compiled exported call (`jax.stages.Compiled`): arrays in and out
    skeleton: Any  # the output with `_Slot`s where its arrays go


class _Exported(NamedTuple):
    exported: Any  # `jax.export.Exported`: array leaves in, arrays out
    skeleton: Any


class _Keyed(NamedTuple):
    """A call's key (what tracing depends on), its digest, and its flattened
    arguments."""

    key: str
    digest: str
    leaves: list
    treedef: Any


class _StoredJit(Generic[_P, _R]):
    """`eqx.filter_jit(fn)` with its traced programs kept in the program store."""

    def __init__(self, fn: Callable[_P, _R], compiler_options: dict | None):
        # `_traced` runs inside the export's `jax.jit` (nested: no compiler options;
        # the exported call's `jax.jit` compiles with them).
        self._traced = eqx.filter_jit(fn)
        self._fn = fn
        # The options it asked for, less those `XLA_FLAGS` decides (`_xla_options`).
        self._compiler_options = _xla_options.compiler_options(compiler_options)
        # One future per key: the program (None: it cannot be stored), resolved once
        # it is built (or read) and compiled; a call that finds another thread
        # building it waits for that instead of building it again.
        self._memo: dict[str, Future[_Program | None]] = {}
        # The same for calls that run unstored (`jitted`), prepared by `prepare`
        # and not yet called (a call takes its key out: JAX's caches hold the rest).
        self._prepared: dict[str, Future[None]] = {}
        self._lock = threading.Lock()
        functools.update_wrapper(self, fn)
        _instances.add(self)

    def _unstored(self) -> Any:
        """The jit an unstored call runs: `jitted`, or inside a JAX transformation
        (a nested jit, vmap, grad: XLA's options belong to the outermost jit) the
        plain one."""
        return self.jitted if _jax_core.trace_state_clean() else self._traced

    @functools.cached_property
    def _xla_compiler_options(self) -> dict:
        """The options its outermost jit compiles with, on both paths. Made on first
        use: whether XLA knows its optional options is asked only when something
        compiles."""
        return _xla_options.supported(self._compiler_options)

    @functools.cached_property
    def jitted(self) -> Any:
        """The call's own jit, for calls that run unstored (`Any`: equinox's jit
        wrapper, called, and `.lower`-ed by `prepare`)."""
        options = self._xla_compiler_options
        if not options:
            return self._traced
        return eqx.filter_jit(self._fn, compiler_options=options)  # pyright: ignore[reportCallIssue]

    def __call__(self, *args: _P.args, **kwargs: _P.kwargs) -> _R:
        found = self._stored_program(args, kwargs)
        if found is not None:
            program, arrays = found
            return _rebuild(program.skeleton, program.run(*arrays))
        if self._prepared:  # wait for a preparation of this call still under way
            keyed = self._keyed(args, kwargs)
            if keyed is not None:
                with self._lock:
                    preparation = self._prepared.pop(keyed.digest, None)
                if preparation is not None:
                    preparation.result()
        return self._unstored()(*args, **kwargs)

    def prepare(self, *args: _P.args, **kwargs: _P.kwargs) -> None:
        """Trace and compile the program that a call with these arguments runs
        (with the store on: trace, export and compile it, or read it from the
        store), without running it: a later call whose arguments have the same
        structure (shapes, dtypes, static values) starts at once. Meant for a
        background thread while other work runs (`identify` prepares its polish and
        its identifiability during the swarm); a call that arrives while it works
        waits for it instead of doing the work twice. Does nothing for calls that
        are themselves traced, or whose arguments the key cannot pin down."""
        if self._stored_program(args, kwargs) is not None:
            return
        keyed = self._keyed(args, kwargs)
        if keyed is None:
            return

        def compile_it() -> None:
            # The call's own jit: its later calls reuse this trace and compilation.
            self._unstored().lower(*args, **kwargs).compile()

        self._once(self._prepared, keyed.digest, compile_it)

    def _keyed(self, args, kwargs) -> "_Keyed | None":
        """The key of a call, or None where it runs as plain `eqx.filter_jit`
        whatever the store (debug options, traced or other-device arguments,
        arguments the key cannot pin down)."""
        if _debugging():
            return None
        arguments = (args, kwargs)
        leaves, treedef = jax.tree_util.tree_flatten(arguments)
        if any(isinstance(leaf, Tracer) for leaf in leaves) or not all(
            _on_default_device(leaf) for leaf in leaves
        ):
            return None
        try:
            # The function itself too: a lambda, a local function or a closure over
            # what cannot be pinned is not.
            function = _encode(self._fn, static=True)
            # The options too: a function compiled with two sets of options (a
            # one-shot and a usual one) keeps two programs, one per key.
            options = f"options={self._compiler_options!r}"
            key = "|".join([_environment(), function, options, _encode(arguments)])
        except _Unpinned:
            return None
        digest = hashlib.sha256(key.encode()).hexdigest()
        return _Keyed(key, digest, leaves, treedef)

    def _once(self, memo: dict, digest: str, build: Callable[[], Any]) -> Any:
        """`build()` once per `digest` in `memo`, whichever thread asks first; the
        others wait for its result (or its exception)."""
        with self._lock:
            future = memo.get(digest)
            building = future is None
            if building:
                future = memo[digest] = Future()
        if building:
            try:
                value = build()
            except BaseException as error:
                with self._lock:
                    del memo[digest]  # a later call tries again
                future.set_exception(error)
                raise
            future.set_result(value)
        return future.result()

    def _stored_program(self, args, kwargs) -> "tuple[_Program, list] | None":
        """The compiled stored program for these arguments and their array leaves,
        or None where the call runs as plain `eqx.filter_jit`."""
        store = _store
        if store is None:
            return None
        keyed = self._keyed(args, kwargs)
        if keyed is None:
            return None
        arrays = [leaf for leaf in keyed.leaves if eqx.is_array(leaf)]

        def build() -> _Program | None:
            _noted(keyed.digest)
            program = self._load_executable(store, keyed)
            if program is None:
                exported = self._load(store, keyed)
                if exported is None:
                    exported = self._build(store, keyed)
                if exported is None:
                    return None
                program = self._compile(store, keyed, exported, arrays)
            return program

        program = self._once(self._memo, keyed.digest, build)
        return None if program is None else (program, arrays)

    def _load(self, store: Path, keyed: _Keyed) -> "_Exported | None":
        """The exported program an earlier process wrote, or `None`."""
        payload = _read(store / f"{keyed.digest}.program")
        if payload is None:
            return None
        stored_key, exported_bytes, skeleton = pickle.loads(payload)
        if stored_key != keyed.key:
            return None
        return _Exported(jax.export.deserialize(bytearray(exported_bytes)), skeleton)

    def _compile(
        self, store: Path, keyed: _Keyed, found: "_Exported", arrays: list
    ) -> _Program:
        """Compile the exported program (here, so that a thread waiting on the
        future finds it compiled) and keep the executable for later processes."""

        def call(*arrays):
            return found.exported.call(*arrays)

        # Named after its key, so that JAX's compilation cache, which keys on the
        # program's text, holds it apart from the same text stored under another
        # key (an older jaxhyst's): a stored executable is one compiled here.
        call.__name__ = call.__qualname__ = f"stored_program_{keyed.digest[:16]}"
        # Every input on the default device, committed or not: one compilation
        # (left to itself, jit compiles again for each mix of committed inputs).
        device = jax.sharding.SingleDeviceSharding(jax.devices()[0])
        run = jax.jit(
            call,
            in_shardings=device,
            compiler_options=self._xla_compiler_options,
        )
        hits = _compilation_cache_hits()
        with _not_written_to_jax_cache():
            compiled = run.lower(*arrays).compile()
        if _compilation_cache_hits() == hits:
            # Not read back from JAX's compilation cache: XLA:CPU serializes such
            # an executable without its kernels, and it would fail when run.
            self._write_executable(store, keyed, compiled, found)
        return _Program(compiled, found.skeleton)

    def _executable_key(self, key: str) -> str:
        """`key` (which names the compiler options) plus what else compiling depends
        on beyond tracing."""
        return "|".join([key, _compile_environment()])

    def _load_executable(self, store: Path, keyed: _Keyed) -> "_Program | None":
        """The executable an earlier process compiled, or `None` (not there,
        written for another key or processor, or one XLA refuses to load); the
        prefetching thread's copy where it has (or is) loading it."""
        expected = self._executable_key(keyed.key)
        loaded = _prefetched(keyed.digest)
        if loaded is _NOT_PREFETCHED:
            path = store / f"{keyed.digest}.executable"
            loaded = _read_executable(path, lambda key: key == expected)
        if loaded is None or loaded.key != expected:
            return None
        return loaded.program

    def _write_executable(
        self, store: Path, keyed: _Keyed, compiled, found: "_Exported"
    ) -> None:
        """Keep `compiled` in the store, where JAX can serialize it."""
        try:
            serialized, in_tree, out_tree = serialize_executable.serialize(compiled)
        except (ValueError, NotImplementedError):
            return  # JAX cannot serialize it: compiled again by the next process
        payload = pickle.dumps(
            (
                self._executable_key(keyed.key),
                # About a sixth of the size, for a few milliseconds either way.
                zlib.compress(serialized, 1),
                in_tree,
                out_tree,
                found.skeleton,
                _uses_lapack(found.exported),
            )
        )
        try:
            _write(store / f"{keyed.digest}.executable", payload)
        except OSError:
            pass  # a full disk, a folder made read-only: run it all the same

    def _build(self, store: Path, keyed: _Keyed) -> "_Exported | None":
        """Trace and export the program, write it to the store and return it; `None`
        if it cannot be stored."""
        leaves, treedef = keyed.leaves, keyed.treedef
        is_array = [eqx.is_array(leaf) for leaf in leaves]
        static = [None if a else leaf for leaf, a in zip(leaves, is_array)]
        found: dict[str, Any] = {}

        def stored(*arrays):
            it = iter(arrays)
            rebuilt = [next(it) if a else s for s, a in zip(static, is_array)]
            args, kwargs = jax.tree_util.tree_unflatten(treedef, rebuilt)
            out = self._traced(*args, **kwargs)  # pyright: ignore[reportCallIssue]
            out_leaves, out_tree = jax.tree_util.tree_flatten(out)
            arrays_out, slots = [], []
            for leaf in out_leaves:
                if eqx.is_array(leaf):
                    slots.append(_Slot(len(arrays_out)))
                    arrays_out.append(leaf)
                else:
                    slots.append(leaf)
            found["skeleton"] = jax.tree_util.tree_unflatten(out_tree, slots)
            return arrays_out

        arrays = [leaf for leaf, a in zip(leaves, is_array) if a]
        stored.__name__ = f"stored_{getattr(self._fn, '__name__', 'program')}"
        exported = _export(stored, arrays)
        if exported is None:
            return None
        skeleton = found["skeleton"]
        try:
            _encode(jax.tree_util.tree_map(lambda s: None, skeleton, is_leaf=_is_slot))
        except _Unpinned:
            return None  # an output pickle could not bring back faithfully
        payload = pickle.dumps((keyed.key, bytes(exported.serialize()), skeleton))
        try:
            _write(store / f"{keyed.digest}.program", payload)
        except OSError:
            pass  # a full disk, a folder made read-only: run it all the same
        return _Exported(exported, skeleton)


class _LoadedExecutable(NamedTuple):
    key: str  # the executable key it was written under (`_executable_key`)
    program: _Program


def _read_executable(
    path: Path, wanted: Callable[[str], bool]
) -> "_LoadedExecutable | None":
    """The executable in `path` and the key it was written under, or `None` (not
    there, damaged, written under a key `wanted` refuses, or one XLA refuses to
    load)."""
    payload = _read(path)
    if payload is None:
        return None
    stored_key, serialized, in_tree, out_tree, skeleton, lapack = pickle.loads(payload)
    if not wanted(stored_key):
        return None
    if lapack:
        _initialize_lapack()
    try:
        compiled = serialize_executable.deserialize_and_load(
            zlib.decompress(serialized), in_tree, out_tree
        )
    except jax.errors.JaxRuntimeError:
        return None  # compiled again and written over
    return _LoadedExecutable(stored_key, _Program(compiled, skeleton))


def _lapack_targets() -> set[str]:
    """jaxlib's CPU LAPACK kernels (linear solves, QR): allowed from the start, so
    that a program using them is not lowered twice to learn their names."""
    try:
        from jaxlib import lapack
    except ImportError:
        return set()
    registrations = getattr(lapack, "registrations", None)
    if registrations is None:
        return set()
    return {entry[0] for entries in registrations().values() for entry in entries}


_LAPACK_TARGETS = frozenset(_lapack_targets())
# Custom calls `_export` lets through: LAPACK's, and those it learns of since.
_allowed_custom_calls: set[str] = set(_LAPACK_TARGETS)


def _uses_lapack(exported) -> bool:
    """Whether the exported program calls jaxlib's CPU LAPACK kernels: whether one
    of their names is among the strings of its serialized module (MLIR bytecode
    keeps them as they are; printing the module as text took 0.03 s a program)."""
    module = bytes(exported.mlir_module_serialized)
    return any(target.encode() in module for target in _LAPACK_TARGETS)


_lapack_lock = threading.Lock()
_lapack_ready = False


def _initialize_lapack() -> None:
    """Point jaxlib's CPU LAPACK kernels at SciPy's LAPACK (about 0.15 s: it imports
    SciPy's), once per process, whichever thread asks first. JAX does this when it
    lowers a program that uses them; an executable loaded without lowering would
    otherwise call a null function and crash. The call is the one `jax.export`'s
    lowering makes (jaxlib has no public name for it; the store's key pins the
    jaxlib version)."""
    global _lapack_ready
    with _lapack_lock:
        if not _lapack_ready:
            from jaxlib import lapack

            lapack._lapack.initialize()  # pyright: ignore[reportPrivateImportUsage]
            _lapack_ready = True


def _not_written_to_jax_cache() -> contextlib.AbstractContextManager:
    """In this thread, JAX's persistent compilation cache writes nothing (it still
    serves what it holds): the store keeps the executable it compiles, and a second
    copy in JAX's cache cost 0.12 s of the swarm's loop in a cold fit, compressed
    and written for nothing. JAX has no public switch for one compilation; its
    minimum compile time, set to infinity, is one (thread-local)."""
    state = getattr(_jax_config, "persistent_cache_min_compile_time_secs", None)
    return contextlib.nullcontext() if state is None else state(math.inf)


_CACHE_HIT = "/jax/compilation_cache/cache_hits"
_this_thread = threading.local()


def _count_cache_hit(event: str, **kwargs) -> None:
    if event == _CACHE_HIT:
        _this_thread.cache_hits = getattr(_this_thread, "cache_hits", 0) + 1


@functools.cache
def _listening() -> None:
    jax.monitoring.register_event_listener(_count_cache_hit)


def _compilation_cache_hits() -> int:
    """How many programs this thread has read from JAX's compilation cache (from
    the first call on)."""
    _listening()
    return getattr(_this_thread, "cache_hits", 0)


def _export(stored, arrays):
    """`jax.export` of `stored`, or `None` if the program cannot be stored (it calls
    back into Python). Custom calls with no compatibility guarantee across JAX
    versions (LAPACK on CPU) are allowed: the key pins the JAX version."""
    from jax import export

    for _ in range(8):
        checks = [
            export.DisabledSafetyCheck.custom_call(n)
            for n in sorted(_allowed_custom_calls)
        ]
        try:
            return export.export(jax.jit(stored), disabled_checks=checks)(*arrays)
        except NotImplementedError as error:
            if _CALLBACKS_REFUSED in str(error):
                return None
            raise
        except ValueError as error:
            if not str(error).startswith(_CUSTOM_CALL_REFUSED):
                raise
            names = set(re.findall(r"custom_call @(\w+)", str(error)))
            if (
                not names
                or names <= _allowed_custom_calls
                or any("callback" in n for n in names)
            ):
                return None
            _allowed_custom_calls.update(names)
    return None


def _debugging() -> bool:
    """Whether a JAX debug option is on (calls then run as JAX runs them)."""
    return any(getattr(jax.config, o) for o in _DEBUG_OPTIONS)


def _on_default_device(leaf) -> bool:
    """False for an array committed to another device than the default one (the
    stored programs run there)."""
    if not isinstance(leaf, jax.Array) or not getattr(leaf, "committed", False):
        return True
    return leaf.sharding.device_set == {jax.devices()[0]}


def _is_slot(x) -> bool:
    return isinstance(x, _Slot)


def _rebuild(skeleton, outputs):
    return jax.tree_util.tree_map(
        lambda s: outputs[s.index] if isinstance(s, _Slot) else s,
        skeleton,
        is_leaf=_is_slot,
    )


def _read(path: Path) -> bytes | None:
    """The payload `_write` wrote to `path`, or `None` if the file is not there,
    cannot be read, or is damaged (then it is built again and written over)."""
    try:
        data = path.read_bytes()
    except OSError:  # not there (the usual case), or unreadable
        return None
    if data[: len(_MAGIC)] != _MAGIC:
        return None
    checksum, _, payload = data[len(_MAGIC) :].partition(b"\n")
    if hashlib.sha256(payload).hexdigest().encode() != checksum:
        return None  # damaged or partly written by an old format
    return payload


def _write(path: Path, payload: bytes) -> None:
    """Write `path` whole or not at all (a temporary file, then a rename)."""
    path.parent.mkdir(mode=0o700, parents=True, exist_ok=True)
    checksum = hashlib.sha256(payload).hexdigest().encode()
    fd, temporary = tempfile.mkstemp(prefix=".program-", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(_MAGIC + checksum + b"\n" + payload)
        os.replace(temporary, path)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise


_instances: "weakref.WeakSet[_StoredJit]" = weakref.WeakSet()


def forget_loaded_programs() -> None:
    """Let go of the executables `stored_jit` holds in this process (JAX's caches,
    which `jax.clear_caches` empties, do not hold them), the prefetched ones
    included; the next call loads its program from the store again.
    `release_if_near_map_limit` calls it."""
    for function in list(_instances):
        with function._lock:
            function._memo.clear()
    run = _prefetch
    if run is not None:
        run.forget()


# The most programs a prefetch list names (a diagnosis of a long real test uses
# about 120).
_PREFETCH_LIMIT = 1000
_NOT_PREFETCHED: Any = object()


class _Prefetch:
    """One `prefetching` block: the programs it used, in the order it first asked
    for them, and the thread loading, ahead of the calls, those the last block that
    began with the same program used."""

    def __init__(self, store: Path):
        self.store = store
        self.lock = threading.Lock()
        self.used: list[str] = []
        # Executables loaded (or being loaded) by the thread, not yet asked for.
        self.loaded: dict[str, Future] = {}
        # Digests a call or the thread has taken: the thread skips them.
        self.taken: set[str] = set()
        self.stop = threading.Event()
        self.thread: threading.Thread | None = None
        self.served = 0  # calls that found their executable loaded by the thread

    def list_path(self, first: str) -> Path:
        return self.store / "prefetch" / f"{first}.list"

    def note(self, digest: str) -> None:
        """A call asked for the program `digest`; the block's first such call
        starts the thread on the list the last block begun by it left."""
        with self.lock:
            if digest in self.used:
                return
            self.used.append(digest)
            if len(self.used) > 1:
                return
        listed = _read(self.list_path(digest))
        if listed is None:
            return
        digests = listed.decode().split()
        if not digests or digests[0] != digest:
            return
        self.thread = threading.Thread(
            target=self._load_ahead,
            args=(digests[1:],),
            name="jaxhyst-prefetch",
            daemon=True,
        )
        self.thread.start()

    def _load_ahead(self, digests: list[str]) -> None:
        environment = _environment() + "|"
        compiling = f"|{_compile_environment()}"  # `_executable_key`'s end

        def wanted(key: str) -> bool:
            return key.startswith(environment) and key.endswith(compiling)

        for digest in digests:
            if self.stop.is_set():
                return
            with self.lock:
                if digest in self.taken:
                    continue
                self.taken.add(digest)
                future = self.loaded[digest] = Future()
            try:
                path = self.store / f"{digest}.executable"
                future.set_result(_read_executable(path, wanted))
            except BaseException as error:  # raised to the call that asks for it
                future.set_exception(error)

    def take(self, digest: str) -> Any:
        """The thread's `_read_executable` result for `digest` (waiting for it if it
        is loading it now), or `_NOT_PREFETCHED`; the thread skips it from now."""
        with self.lock:
            future = self.loaded.pop(digest, None)
            self.taken.add(digest)
        if future is None:
            return _NOT_PREFETCHED
        found = future.result()
        if found is not None:
            self.served += 1
        return found

    def forget(self) -> None:
        with self.lock:
            self.loaded.clear()

    def finish(self) -> None:
        """Stop the thread (after the executable it is loading) and keep this
        block's list for the next block that begins with the same program."""
        self.stop.set()
        if self.thread is not None:
            self.thread.join()
        self.forget()
        if len(self.used) > 1:
            listed = "\n".join(self.used[:_PREFETCH_LIMIT]).encode()
            try:
                _write(self.list_path(self.used[0]), listed)
            except OSError:
                pass  # a full disk, a folder made read-only: nothing is lost


_prefetch: _Prefetch | None = None


def _noted(digest: str) -> None:
    run = _prefetch
    if run is not None:
        run.note(digest)


def _prefetched(digest: str) -> Any:
    run = _prefetch
    return _NOT_PREFETCHED if run is None else run.take(digest)


@contextlib.contextmanager
def prefetching() -> Iterator[None]:
    """Load stored executables ahead of the calls that need them, in a background
    thread, while the block runs. The block's first stored program names a list,
    kept in the store, of the programs the last block that began with it used, in
    the order it asked for them: the thread loads those (about 0.1-0.5 s each on
    the 2-core machine, most of it outside Python's lock) while the block computes,
    and a call finds its executable loaded, or waits for the one being loaded. At
    the end the block's own list replaces it. A command run twice (the same
    recording, or one of the same length and kind) thus loads most of what it runs
    in the background. Programs the list names that the block does not use are
    loaded for nothing (a recording of another kind that begins the same way).
    With the store off, JAX's debug options on, or inside another such block, it
    does nothing; the CLI runs every command in one."""
    global _prefetch
    store = _store
    if store is None or _debugging() or _prefetch is not None:
        yield
        return
    run = _prefetch = _Prefetch(store)
    try:
        yield
    finally:
        _prefetch = None
        run.finish()


class _OneShotOrUsual(Generic[_P, _R]):
    """A `stored_jit` with one-shot options: the function stored twice, compiled
    with its usual options and with the one-shot ones added; a call (or a
    `prepare`) takes the one its context asks for (`_xla_options.in_one_shot`)."""

    def __init__(
        self, fn: Callable[_P, _R], compiler_options: dict | None, one_shot: dict
    ):
        self.usual = _StoredJit(fn, compiler_options)
        self.one_shot = _StoredJit(fn, {**(compiler_options or {}), **one_shot})
        if self.one_shot._compiler_options == self.usual._compiler_options:
            self.one_shot = self.usual  # `XLA_FLAGS` decides them: one program
        functools.update_wrapper(self, fn)

    def _now(self) -> _StoredJit[_P, _R]:
        return self.one_shot if _xla_options.in_one_shot() else self.usual

    def __call__(self, *args: _P.args, **kwargs: _P.kwargs) -> _R:
        return self._now()(*args, **kwargs)

    def prepare(self, *args: _P.args, **kwargs: _P.kwargs) -> None:
        """`_StoredJit.prepare` of the program a call here would run."""
        self._now().prepare(*args, **kwargs)


def stored_jit(
    fn: Callable[_P, _R] | None = None,
    *,
    compiler_options: dict | None = None,
    one_shot_options: dict | None = None,
) -> Any:
    """`eqx.filter_jit` whose traced programs are kept in the program store when it
    is on (see the module docstring); with the store off it is `eqx.filter_jit`.
    Use it as `@stored_jit` or `@stored_jit(compiler_options=...)` (XLA options for
    the outermost jit; see `_xla_options` for those an XLA may not know).
    `one_shot_options` are added in a `_xla_options.one_shot()` block: for programs
    whose compilation costs more than the few runs a fit gives them."""
    if fn is None:
        return functools.partial(
            stored_jit,
            compiler_options=compiler_options,
            one_shot_options=one_shot_options,
        )
    if one_shot_options:
        return _OneShotOrUsual(fn, compiler_options, one_shot_options)
    return _StoredJit(fn, compiler_options)


@contextlib.contextmanager
def preparing(prepare: Callable[[], None] | None) -> Iterator[None]:
    """Run `prepare` (calls of `stored_jit`'s `prepare`) in a background thread while
    the block runs, and wait for it at the block's end, raising what it raised. On
    two cores the programs a pipeline needs later compile while its first stage
    runs. With `prepare=None`, or JAX's debug options on (`jax_disable_jit`,
    `jax_debug_nans`: calls then run op by op), it does nothing."""
    if prepare is None or _debugging():
        yield
        return
    with ThreadPoolExecutor(1, thread_name_prefix="jaxhyst-prepare") as pool:
        # In the caller's context: it prepares what the caller will call.
        done = pool.submit(contextvars.copy_context().run, prepare)
        yield
        done.result()
