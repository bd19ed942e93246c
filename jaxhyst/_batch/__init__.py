"""Batches of records on Dask: the manifest (`_manifest`), one record's task run on
a worker (`_task`), the batch folder on disk (`_store`), the summary rebuilt from it
(`_summary`), and `batch`, which drives them on a cluster (`_run`)."""

from ._manifest import (
    Manifest as Manifest,
    ManifestError as ManifestError,
    read_manifest as read_manifest,
)
from ._run import (
    BatchInterrupted as BatchInterrupted,
    BatchResult as BatchResult,
    LocalWorkers as LocalWorkers,
    SchedulerAddress as SchedulerAddress,
    batch as batch,
)
from ._store import BatchLockedError as BatchLockedError
from ._summary import SummaryRow as SummaryRow, write_summary as write_summary
