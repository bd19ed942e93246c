"""mkdocs hook: put files that live outside `docs/` on the site, as they stand.

- `notebooks/*.ipynb`: the repository's notebooks (the test suite executes them in
  place). The mkdocs-jupyter plugin turns them into pages, rendered with the outputs
  saved in them and never executed at build time (`execute: false` in mkdocs.yml).
- `benchmarks/README.md` (the benchmark results, the page `benchmarks/`),
  `benchmarks/HISTORY.md` and the scripts `benchmarks/*.py` they link to: the pages
  are the files themselves, not copies, so their relative links keep working.

Each file keeps its path relative to the repository root as its path on the site.
"""

from pathlib import Path

from mkdocs.plugins import event_priority
from mkdocs.structure.files import File


# (folder, glob) pairs, relative to the repository root (where mkdocs.yml is).
_EXTERNAL = (
    ("notebooks", "*.ipynb"),
    ("benchmarks", "*.md"),
    ("benchmarks", "*.py"),
)


@event_priority(100)  # before mkdocs-jupyter's on_files (priority 0)
def on_files(files, config):
    root = Path(config.config_file_path).resolve().parent
    for folder, pattern in _EXTERNAL:
        for path in sorted((root / folder).glob(pattern)):
            files.append(
                File(
                    f"{folder}/{path.name}",
                    src_dir=str(root),
                    dest_dir=config.site_dir,
                    use_directory_urls=config.use_directory_urls,
                )
            )
    return files
