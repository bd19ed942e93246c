"""The command line's voice of the output rule (`jaxhyst._files`): existing outputs
are replaced only with `--force`, and every command checks all its outputs before
any computation, so that a refused run costs nothing and leaves nothing behind."""

import dataclasses
import os
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

from .._diagnose._results import Diagnosis
from .._files import (
    Refusal,
    output_folder,
    prepare_parent,
    refuse_existing,
    refuse_folder,
)
from .._model_files import model_file_dict
from .._recording import Recording
from .._serialise import write_json as _write_json


FORCE = Refusal(
    switch="--force",
    replaces="the outputs of an earlier run",
    otherwise="pick other output paths",
)
"""How the command line refuses to replace files."""


def check_files(files: Sequence[tuple[str, Path]], force: bool) -> None:
    """Refuse output files (option, path) that are folders, or that exist unless
    `force`. Creates nothing."""
    for option, path in files:
        refuse_folder(path, option=option)
    refuse_existing([path for _, path in files], overwrite=force, refusal=FORCE)


def check_folder(
    option: str, folder: str | os.PathLike, names: Iterable[str], force: bool
) -> list[Path]:
    """The files `folder/name`, after checking `folder` is (or can become) a folder
    and none of them exists unless `force`. Creates nothing."""
    refusal = dataclasses.replace(FORCE, otherwise=f"pick another {option}")
    return output_folder(folder, names, overwrite=force, refusal=refusal, option=option)


def write_json(data: Any, path: Path, force: bool) -> None:
    """Write `data` as JSON to `path` (creating its folder) and say so."""
    _write_json(data, prepare_parent(path), overwrite=force, refusal=FORCE)
    print(f"wrote {path}")


def print_written(paths: Iterable[Path]) -> None:
    for path in paths:
        print(f"wrote {path}")


def diagnosis_model_file(
    diagnosis: Diagnosis, recording: Recording | Sequence[Recording]
) -> dict[str, object]:
    """The model file of the final (diagnosed) model, embedded in the JSON."""
    return model_file_dict(
        diagnosis.final_model,
        recording=recording,
        family=diagnosis.family,
        effects=diagnosis.effects,
    )
