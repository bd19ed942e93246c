"""The `jaxhyst` command line.

One module per command (`_simulate`, `_fit`, `_diagnose`, `_evaluate`,
`_compensate`, `_batch`, `_demo`), each a pair of functions: `add_parser(subparsers)` declares
its options and sets `run=run`, and `run(args) -> int` does the work by calling the
library, then prints and writes. `_choices` is the one table from option values
(`--model`, `--signal`, `--preset`) to objects; `_options` holds the options and
readers several commands share; `_outputs` the command line's voice of the output
rule of `jaxhyst._files` (nothing is replaced without `--force`).

`main` (in `_main`) turns user errors (bad options, bad values, files in the way,
unreadable recordings, missing matplotlib) into one line `jaxhyst: error: ...` on
stderr and exit status 2, without a traceback; warnings go to stderr as
`jaxhyst: warning: ...`.
"""

from ._main import main as main, script as script
