"""A persistent JAX compilation cache for the command line and the demo.

Nothing here runs on `import jaxhyst`: a library must not change JAX's global
configuration behind its user's back. The CLI (`jaxhyst ...`) calls
`enable_compilation_cache` first thing; a notebook or script may call it too.
"""

import os
import sys
import tempfile
from pathlib import Path


ENV_VAR = "JAXHYST_CACHE_DIR"

_warned = False


def _user_cache_root() -> Path:
    """The platform's per-user cache folder (no third-party dependency)."""
    if sys.platform == "win32":
        local = os.environ.get("LOCALAPPDATA")
        return Path(local) if local else Path.home() / "AppData" / "Local"
    if sys.platform == "darwin":
        return Path.home() / "Library" / "Caches"
    xdg = os.environ.get("XDG_CACHE_HOME")
    # The XDG spec: a relative XDG_CACHE_HOME is invalid and is ignored.
    if xdg and os.path.isabs(xdg):
        return Path(xdg)
    return Path.home() / ".cache"


def compilation_cache_dir() -> Path | None:
    """Where `enable_compilation_cache` keeps compiled programs, or `None` if the
    cache is turned off. Creates nothing.

    **Returns:**

    `$JAXHYST_CACHE_DIR` if that environment variable is set (`~` expanded; made
    absolute), `None` if it is set to an empty string; otherwise the per-user cache
    folder: `$XDG_CACHE_HOME/jaxhyst/jax` (or `~/.cache/jaxhyst/jax`) on Linux and
    other Unixes, `~/Library/Caches/jaxhyst/jax` on macOS and
    `%LOCALAPPDATA%\\jaxhyst\\jax` on Windows.

    **Raises:**

    `RuntimeError` if the default is wanted but the home folder cannot be
    determined.
    """
    value = os.environ.get(ENV_VAR)
    if value is not None:
        if not value.strip():
            return None
        return Path(value).expanduser().absolute()
    return _user_cache_root() / "jaxhyst" / "jax"


def _warn_once(message: str) -> None:
    global _warned
    if not _warned:
        _warned = True
        print(f"jaxhyst: warning: {message}", file=sys.stderr, flush=True)


def _check_writable(path: Path) -> None:
    """Create `path` (private to the user where it is created) and prove that a
    file can be written in it; raises `OSError` otherwise."""
    path.mkdir(mode=0o700, parents=True, exist_ok=True)
    fd, probe = tempfile.mkstemp(prefix=".jaxhyst-probe-", dir=path)
    try:
        os.write(fd, b"ok")
    finally:
        os.close(fd)
        os.unlink(probe)


def enable_compilation_cache() -> Path | None:
    """Turn on JAX's persistent compilation cache in `compilation_cache_dir()`, so
    that a later process running the same programs loads them from disk instead of
    compiling them again (a fresh `jaxhyst fit` spends most of its time compiling).

    It sets `jax_compilation_cache_dir`, and makes every compiled program eligible
    for the cache, however small or quick to compile
    (`jax_persistent_cache_min_compile_time_secs = 0`,
    `jax_persistent_cache_min_entry_size_bytes = -1`): on CPU many programs take
    well under JAX's default threshold of one second each, and together they are
    most of the start-up time. XLA's extra caches (`jax_persistent_cache_enable_xla_
    caches`: GPU autotuning and kernel caches) are left at JAX's default; XLA:CPU
    has none. Call it before the computations it should cache: JAX opens the folder
    at the first compilation after it is set and keeps it for the rest of the
    process. Calling it again is harmless.

    Entries are keyed by a hash of the program, the jaxlib version, the backend,
    the XLA flags and the compile options, so several versions of jaxhyst or JAX may
    share the folder, and the folder is safe to delete at any time (it grows without
    a size limit; delete it to reclaim the space).

    Sharing between processes: JAX (0.10) writes each entry as one file,
    `<key>-cache`, with a plain write (no temporary file and rename, and no lock
    unless a maximum cache size is set, which this does not do), and never writes
    over an entry that exists. Two processes that share the folder therefore never
    block each other; a process that reads an entry while another is still writing
    it may find it incomplete, in which case its decompression fails (a truncated
    zlib or zstandard stream does not decompress), JAX warns ("Error reading persistent
    compilation cache entry") and compiles the program itself. The worst case is a
    warning and a compilation, never a wrong result, nor a failed command unless
    warnings are turned into errors (`python -W error`, pytest's `filterwarnings =
    error`); a file left truncated by a process killed while writing it keeps
    causing that warning until the folder is deleted. The cache holds executable
    code: do not point it at a folder that others can write.

    **Returns:**

    The cache folder, or `None` if the cache is off: `JAXHYST_CACHE_DIR` is set to
    an empty string (nothing is configured), or the folder cannot be created or
    written; then one line on stderr names the folder and `JAXHYST_CACHE_DIR`, once
    per process, and everything runs as before, only without the cache. It never
    raises.
    """
    import jax

    try:
        path = compilation_cache_dir()
    except RuntimeError as error:
        _warn_once(
            f"no compilation cache ({error}); set {ENV_VAR} to a writable folder, "
            "or to an empty string to silence this"
        )
        return None
    if path is None:
        return None
    try:
        _check_writable(path)
    except OSError as error:
        reason = error.strerror or type(error).__name__
        _warn_once(
            f"cannot use the compilation cache folder {str(path)!r} ({reason}); "
            f"running without it. Set {ENV_VAR} to a writable folder, or to an "
            "empty string to turn the cache off"
        )
        return None
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
    jax.config.update("jax_persistent_cache_min_entry_size_bytes", -1)
    jax.config.update("jax_compilation_cache_dir", str(path))
    return path
