"""The persistent compilation cache of the CLI: where it lives, how the environment
variable moves or disables it, what happens when it cannot be written, and that a
second process loads what a first one compiled (fresh processes, no timings)."""

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import jax
import pytest

from jaxhyst import _cache
from jaxhyst._cache import compilation_cache_dir, enable_compilation_cache


_OPTIONS = (
    "jax_compilation_cache_dir",
    "jax_persistent_cache_min_compile_time_secs",
    "jax_persistent_cache_min_entry_size_bytes",
)


def _option(name: str):
    return getattr(jax.config, name)


@pytest.fixture
def jax_cache_config(monkeypatch):
    """Restore JAX's cache options afterwards, and start with no warning issued."""
    monkeypatch.setattr(_cache, "_warned", False)
    before = {name: _option(name) for name in _OPTIONS}
    yield before
    for name, value in before.items():
        jax.config.update(name, value)


@pytest.fixture
def no_env(monkeypatch):
    for name in ("JAXHYST_CACHE_DIR", "XDG_CACHE_HOME", "LOCALAPPDATA"):
        monkeypatch.delenv(name, raising=False)
    return monkeypatch


@pytest.mark.parametrize(
    "platform, xdg, parts",
    [
        ("linux", False, (".cache",)),
        ("linux", True, ("xdg",)),
        ("freebsd14", False, (".cache",)),
        ("darwin", False, ("Library", "Caches")),
        ("darwin", True, ("Library", "Caches")),  # XDG is not macOS's convention
    ],
)
def test_default_dir_unix(no_env, tmp_path, platform, xdg, parts):
    no_env.setattr(sys, "platform", platform)
    no_env.setenv("HOME", str(tmp_path))
    if xdg:
        no_env.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert compilation_cache_dir() == tmp_path.joinpath(*parts, "jaxhyst", "jax")


def test_relative_xdg_cache_home_is_ignored(no_env, tmp_path):
    no_env.setattr(sys, "platform", "linux")
    no_env.setenv("HOME", str(tmp_path))
    no_env.setenv("XDG_CACHE_HOME", "relative/cache")
    assert compilation_cache_dir() == tmp_path / ".cache" / "jaxhyst" / "jax"


def test_default_dir_windows(no_env, tmp_path):
    no_env.setattr(sys, "platform", "win32")
    no_env.setenv("LOCALAPPDATA", str(tmp_path / "Local"))
    assert compilation_cache_dir() == tmp_path / "Local" / "jaxhyst" / "jax"
    no_env.delenv("LOCALAPPDATA")
    no_env.setenv("HOME", str(tmp_path))
    expected = tmp_path / "AppData" / "Local" / "jaxhyst" / "jax"
    assert compilation_cache_dir() == expected


def test_env_var_moves_it(no_env, tmp_path):
    no_env.setenv("JAXHYST_CACHE_DIR", str(tmp_path / "elsewhere"))
    no_env.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert compilation_cache_dir() == tmp_path / "elsewhere"
    no_env.setenv("HOME", str(tmp_path))
    no_env.setenv("JAXHYST_CACHE_DIR", "~/mine")
    assert compilation_cache_dir() == tmp_path / "mine"
    no_env.chdir(tmp_path)
    no_env.setenv("JAXHYST_CACHE_DIR", "relative")
    assert compilation_cache_dir() == tmp_path / "relative"  # made absolute


@pytest.mark.parametrize("value", ["", "  "])
def test_empty_env_var_turns_it_off(no_env, jax_cache_config, capsys, value):
    no_env.setenv("JAXHYST_CACHE_DIR", value)
    assert compilation_cache_dir() is None
    assert enable_compilation_cache() is None
    for name, before in jax_cache_config.items():
        assert _option(name) == before  # configured nothing
    assert capsys.readouterr().err == ""


def test_enable_configures_jax(no_env, jax_cache_config, tmp_path, capsys):
    target = tmp_path / "new" / "cache"
    no_env.setenv("JAXHYST_CACHE_DIR", str(target))
    assert enable_compilation_cache() == target
    assert target.is_dir() and list(target.iterdir()) == []  # the probe is gone
    if os.name == "posix":
        assert target.stat().st_mode & 0o777 == 0o700
    assert _option("jax_compilation_cache_dir") == str(target)
    assert _option("jax_persistent_cache_min_compile_time_secs") == 0.0
    assert _option("jax_persistent_cache_min_entry_size_bytes") == -1
    assert enable_compilation_cache() == target  # again: harmless
    assert capsys.readouterr().err == ""


def _unusable(tmp_path: Path, how: str, monkeypatch) -> Path:
    if how == "under a file":
        blocker = tmp_path / "a-file"
        blocker.write_text("not a folder")
        return blocker / "cache"
    if how == "write refused":  # as a read-only folder is, even for root
        folder = tmp_path / "refusing"
        folder.mkdir()

        def refuse(*args, **kwargs):
            raise PermissionError(13, "Permission denied")

        monkeypatch.setattr(_cache.tempfile, "mkstemp", refuse)
        return folder
    folder = tmp_path / "read-only"
    folder.mkdir()
    folder.chmod(0o500)
    return folder / "cache"


@pytest.mark.parametrize(
    "how",
    [
        "under a file",
        "write refused",
        pytest.param(
            "read-only parent",
            marks=pytest.mark.skipif(
                os.name != "posix" or os.geteuid() == 0,
                reason="needs POSIX permissions that apply (not root)",
            ),
        ),
    ],
)
def test_unwritable_dir_warns_once_and_runs_without(
    no_env, jax_cache_config, tmp_path, capsys, how
):
    target = _unusable(tmp_path, how, no_env)
    no_env.setenv("JAXHYST_CACHE_DIR", str(target))
    try:
        assert enable_compilation_cache() is None
        assert enable_compilation_cache() is None
    finally:
        if target.parent.name == "read-only":
            target.parent.chmod(0o700)  # so that pytest can remove tmp_path
    err = capsys.readouterr().err
    assert err.count("\n") == 1, err  # one line, once
    assert str(target) in err and "JAXHYST_CACHE_DIR" in err
    assert err.startswith("jaxhyst: warning: ")
    for name, before in jax_cache_config.items():
        assert _option(name) == before


_CHILD = textwrap.dedent(
    """
    import json

    import jax
    import jax.numpy as jnp

    from jaxhyst import enable_compilation_cache

    events = {"hits": 0, "misses": 0}


    def listener(event, **kwargs):
        if event == "/jax/compilation_cache/cache_hits":
            events["hits"] += 1
        elif event == "/jax/compilation_cache/cache_misses":  # = entries written
            events["misses"] += 1


    jax.monitoring.register_event_listener(listener)
    path = enable_compilation_cache()
    value = jax.jit(lambda x: jnp.sin(x) * 2.0 + x**2)(jnp.linspace(0.0, 1.0, 5))
    print(json.dumps({"path": str(path), "sum": float(value.sum()), **events}))
    """
)


def _run_child(cache: Path) -> dict:
    env = dict(os.environ, JAXHYST_CACHE_DIR=str(cache), JAX_PLATFORMS="cpu")
    env.pop("JAX_COMPILATION_CACHE_DIR", None)
    env.pop("JAX_ENABLE_COMPILATION_CACHE", None)
    result = subprocess.run(
        [sys.executable, "-c", _CHILD],
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.returncode == 0, result.stderr
    assert "warning" not in result.stderr.lower(), result.stderr
    return json.loads(result.stdout.strip().splitlines()[-1])


def _entries(cache: Path) -> set[str]:
    return {p.name for p in cache.iterdir() if p.name.endswith("-cache")}


def test_second_process_compiles_nothing_new(tmp_path):
    cache = tmp_path / "jax-cache"
    first = _run_child(cache)
    assert first["path"] == str(cache)
    assert first["misses"] >= 1  # compiled, and wrote what it compiled
    written = _entries(cache)
    assert len(written) >= first["misses"]
    second = _run_child(cache)
    assert second["misses"] == 0  # compiled nothing that was not in the cache
    assert second["hits"] >= 1
    assert _entries(cache) == written
    assert second["sum"] == first["sum"]


def test_the_package_starts_without_the_reference_solver():
    # Every command pays for its imports; diffrax serves only `DiffraxSolver`
    # (the reference), so it is imported when that solver is first built.
    code = (
        "import sys, jaxhyst, jaxhyst._cli._main\n"
        "assert 'diffrax' not in sys.modules, 'diffrax imported at start'\n"
        "solver = jaxhyst.DiffraxSolver()\n"
        "assert 'diffrax' in sys.modules\n"
        "print(type(solver.solver).__name__)\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=False
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "Tsit5"


def test_one_shot_commands_compile_quickly_and_a_diagnosis_does_not(monkeypatch):
    from jaxhyst._cli import _main

    monkeypatch.setattr(_main, "_jaxlib_version", lambda: (0, 10))
    quick = "--xla_cpu_use_fusion_emitters=false"
    assert _main.quick_compile_flags(["fit", "r.csv"], {}) == quick
    assert (
        _main.quick_compile_flags(["fit"], {"XLA_FLAGS": "--a=1"}) == f"--a=1 {quick}"
    )
    assert _main.quick_compile_flags(["diagnose", "r.csv"], {}) is None
    assert _main.quick_compile_flags(["demo"], {}) is None
    assert _main.quick_compile_flags(["--help"], {}) is None
    # The user's choice of emitters wins, and an unknown jaxlib gets no flag.
    mine = {"XLA_FLAGS": "--xla_cpu_use_fusion_emitters=true"}
    assert _main.quick_compile_flags(["fit"], mine) is None
    monkeypatch.setattr(_main, "_jaxlib_version", lambda: (0, 99))
    assert _main.quick_compile_flags(["fit"], {}) is None


def test_the_installed_jaxlib_accepts_the_quick_compile_flag():
    # The flag is set only for jaxlib releases known to have it; this one runs it.
    from jaxhyst._cli import _main

    low, high = _main._QUICK_COMPILE_JAXLIB
    if not low <= _main._jaxlib_version() < high:
        pytest.skip("this jaxlib is outside the releases known to have the flag")
    env = dict(os.environ, XLA_FLAGS=_main._QUICK_COMPILE_FLAG, JAX_PLATFORMS="cpu")
    done = subprocess.run(
        [sys.executable, "-c", "import jax, jax.numpy as j; print(j.sin(1.0))"],
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 0, done.stderr
