import os

import jax


jax.config.update("jax_enable_x64", True)
jax.config.update("jax_numpy_rank_promotion", "raise")
# The CLI turns on the persistent compilation cache; tests that call `main()` run
# without it (no writes to the user's cache folder, no sharing between test runs)
# unless JAXHYST_CACHE_DIR is set. tests/test_cache.py sets its own folders.
os.environ.setdefault("JAXHYST_CACHE_DIR", "")
