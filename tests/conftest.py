import gc
import os

import jax
import pytest


jax.config.update("jax_enable_x64", True)
jax.config.update("jax_numpy_rank_promotion", "raise")
# The CLI turns on the persistent compilation cache; tests that call `main()` run
# without it (no writes to the user's cache folder, no sharing between test runs)
# unless JAXHYST_CACHE_DIR is set. tests/test_cache.py sets its own folders.
os.environ.setdefault("JAXHYST_CACHE_DIR", "")


@pytest.fixture(autouse=True, scope="module")
def _release_compiled_programs():
    """Release each test module's compiled programs after it. Every compiled CPU
    program holds memory maps (about 80); one process running the whole suite
    would pass the kernel's limit on them (vm.max_map_count, 65530 by default),
    and XLA's compiler then crashes with a segmentation fault."""
    yield
    jax.clear_caches()
    gc.collect()
