"""The batch's folder on disk: `OUT/records/<name>/` per record, written through a
temporary folder renamed into place, the `done` file that lets a rerun skip a
record, and the lock that keeps two batches out of one folder.

A record folder is whole or absent: the task writes into
`OUT/records/.tmp-<name>-<random>/` and renames it to `OUT/records/<name>` as its last
step (a rename within one file system is atomic). A worker killed mid-record leaves
only a `.tmp-*` folder, which the next batch on `OUT` deletes.
"""

import dataclasses
import hashlib
import json
import os
import shutil
import socket
import uuid
from pathlib import Path


DONE = "done"
"""The file of a finished record: what it was run with (`DoneStamp` as JSON)."""
ERROR = "error.txt"
"""The file of a failed record: its one-line error."""
LOCK = "batch.lock"
RECORDS = "records"
TEMPORARY = ".tmp-"


class BatchLockedError(OSError):
    """Another batch is writing the output folder."""


@dataclasses.dataclass(frozen=True)
class DoneStamp:
    """What a finished record was made from: a rerun skips the record only when all
    of these are unchanged.

    - `inputs_sha256`: checksum of the recording file's bytes.
    - `command`: `diagnose` or `fit`.
    - `options`: the record's command-line options (outputs excluded).
    - `version`: jaxhyst's version.
    """

    inputs_sha256: str
    command: str
    options: tuple[str, ...]
    version: str

    def to_json(self) -> str:
        data = dataclasses.asdict(self)
        data["options"] = list(self.options)
        return json.dumps(data, indent=1)

    @classmethod
    def from_json(cls, text: str) -> "DoneStamp":
        data = json.loads(text)
        return cls(
            inputs_sha256=str(data["inputs_sha256"]),
            command=str(data["command"]),
            options=tuple(str(o) for o in data["options"]),
            version=str(data["version"]),
        )


def file_sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as file:
        for block in iter(lambda: file.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def records_folder(out: Path) -> Path:
    return out / RECORDS


def record_folder(out: Path, name: str) -> Path:
    return records_folder(out) / name


def read_done(folder: Path) -> DoneStamp | None:
    """The record's `done` stamp, or None (not finished, or unreadable)."""
    try:
        return DoneStamp.from_json((folder / DONE).read_text(encoding="utf-8"))
    except (OSError, ValueError, KeyError, TypeError):
        return None


def temporary_folder(out: Path, name: str) -> Path:
    """A fresh temporary folder for one attempt at record `name`."""
    folder = records_folder(out) / f"{TEMPORARY}{name}-{uuid.uuid4().hex[:8]}"
    folder.mkdir(parents=True)
    return folder


def commit(temporary: Path, final: Path) -> None:
    """Rename the finished `temporary` folder to `final`, replacing an earlier
    attempt's folder (a failed record being redone). `final` is never half there:
    an old folder is first moved aside, then the new one renamed into place."""
    old = None
    if final.exists():
        old = final.with_name(f"{TEMPORARY}old-{final.name}-{uuid.uuid4().hex[:8]}")
        os.rename(final, old)
    os.rename(temporary, final)
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)


def remove_temporary(out: Path) -> None:
    """Delete the temporary folders attempts left behind (killed workers)."""
    folder = records_folder(out)
    if folder.is_dir():
        for each in folder.iterdir():
            if each.name.startswith(TEMPORARY):
                shutil.rmtree(each, ignore_errors=True)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # someone else's process
        return True
    return True


class BatchLock:
    """`OUT/batch.lock`, holding the pid and host of the batch writing `OUT`.

    A lock left by a batch that is gone (its pid no longer runs on this host) is
    stale and taken over; a lock of a live batch, or of another host, is refused
    with the fix."""

    def __init__(self, out: Path):
        self.path = out / LOCK
        self.held = False

    def acquire(self) -> None:
        self.path.parent.mkdir(parents=True, exist_ok=True)
        me = f"{os.getpid()} {socket.gethostname()}\n"
        for _ in range(2):
            try:
                fd = os.open(self.path, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
            except FileExistsError:
                if self._stale():
                    self.path.unlink(missing_ok=True)
                    continue
                raise BatchLockedError(self._refusal()) from None
            with os.fdopen(fd, "w") as file:
                file.write(me)
            self.held = True
            return
        raise BatchLockedError(self._refusal())

    def _owner(self) -> tuple[int, str] | None:
        try:
            pid, host = self.path.read_text().split()
            return int(pid), host
        except (OSError, ValueError):
            return None

    def _stale(self) -> bool:
        owner = self._owner()
        if owner is None:
            return False
        pid, host = owner
        return host == socket.gethostname() and not _alive(pid)

    def _refusal(self) -> str:
        owner = self._owner()
        who = (
            "another batch" if owner is None else f"batch pid {owner[0]} on {owner[1]}"
        )
        return (
            f"--out {str(self.path.parent)!r} is being written by {who} "
            f"({self.path}); wait for it to finish, pick another --out, or delete "
            "the lock file if that batch is gone."
        )

    def release(self) -> None:
        if self.held:
            self.path.unlink(missing_ok=True)
            self.held = False

    def __enter__(self) -> "BatchLock":
        self.acquire()
        return self

    def __exit__(self, *exc) -> None:
        self.release()
