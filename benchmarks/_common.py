"""What the benchmark scripts share: progress logging, the machine and versions,
command-line options, JSON results, figure files, the synthetic suites' scoring, and
the batch (`jh.batch`) in which the diagnosis suites diagnose their records.

The scripts are run as `python benchmarks/<script>.py`, which puts this folder on
`sys.path`, so they import it as `from _common import ...` (a test that imports a
script puts the folder on `sys.path` the same way).

Importing this module is cheap and imports neither JAX nor NumPy nor jaxhyst: the
parent process of `swarm_throughput.py` must not import JAX, and `fit_speed.py`
times its child's imports. The functions that need them import them when called.
"""

import argparse
import importlib.metadata
import math
import os
import platform
import statistics
import subprocess
import sys
import time
from collections import Counter
from collections.abc import Iterator
from datetime import datetime
from pathlib import Path
from typing import Any, NamedTuple


START = time.perf_counter()
CORE_PACKAGES = ("jaxhyst", "jax", "jaxlib", "numpy", "equinox", "optimistix")
DATA_DIR_DEFAULT = (
    "jh.datasets.default_data_dir(), i.e. $JAXHYST_DATA_DIR or ../shared/data"
)


# ------------------------------------------------------------ the command line


def add_subset(parser, flag: str, choices: list[str], help: str | None = None) -> None:
    """`flag` takes one or more of `choices` (default: all of them)."""
    parser.add_argument(
        flag, nargs="+", default=list(choices), choices=list(choices), help=help
    )


def cli_command() -> list[str]:
    """The `jaxhyst` console script beside this interpreter, else `python -m`."""
    name = "jaxhyst.exe" if os.name == "nt" else "jaxhyst"
    script = os.path.join(os.path.dirname(sys.executable), name)
    if os.path.isfile(script):
        return [script]
    return [sys.executable, "-m", "jaxhyst"]


def add_baseline(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--baseline",
        metavar="TREE",
        help="also time the command from another checkout (a git worktree of an "
        "earlier commit, put on PYTHONPATH), interleaved with this tree's, and give "
        "this tree's medians as ratios of the baseline's",
    )


def launcher(baseline: str | None) -> list[str]:
    """The command line's launcher: `python -m jaxhyst` when a baseline checkout
    is timed too (the same launcher for both trees), else `cli_command()`."""
    if baseline:
        return [sys.executable, "-m", "jaxhyst"]
    return cli_command()


def from_tree(env: dict[str, str], tree: str | None) -> dict[str, str]:
    """`env` with jaxhyst imported from checkout `tree` (None: this one)."""
    if tree is None:
        return env
    return dict(env, PYTHONPATH=os.path.abspath(tree))


def add_bytecode(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--no-bytecode-cache",
        action="store_true",
        help="children compile every module from source, as with "
        "PYTHONDONTWRITEBYTECODE set (default: bytecode cached, as a user's Python "
        "does)",
    )


def child_environment(pycache: str | None, **variables: str) -> dict[str, str]:
    """The environment of a timed child process: os.environ plus `variables`,
    without XLA_FLAGS. With `pycache` (a folder), Python caches bytecode there, as
    a user's Python does beside the sources: PYTHONDONTWRITEBYTECODE, which this
    workplace's machines set, would make every fresh process compile each jaxhyst
    module from source (about 0.5 s). Call `warm_bytecode` before timing."""
    env = dict(os.environ, **variables)
    env.pop("XLA_FLAGS", None)
    if pycache is not None:
        env.pop("PYTHONDONTWRITEBYTECODE", None)
        env["PYTHONPYCACHEPREFIX"] = pycache
    return env


def warm_bytecode(env: dict[str, str]) -> None:
    """Import jaxhyst once under `env`, so its bytecode is cached before timing."""
    subprocess.run([sys.executable, "-c", "import jaxhyst"], env=env, check=True)


def cache_size(folder) -> tuple[int, int]:
    """What `JAXHYST_CACHE_DIR=folder` holds: JAX's compilation-cache entries, how
    many and their bytes."""
    entries = [e for e in os.scandir(folder) if e.name.endswith("-cache")]
    return len(entries), sum(e.stat().st_size for e in entries)


# --------------------------------------------------------------------------- logging


def script_name() -> str:
    """The running script's name without `.py` (for messages)."""
    return Path(sys.argv[0]).stem or "benchmark"


def log(message: str) -> None:
    """A progress line on stderr, stamped with the seconds since the process began
    (the results go to stdout)."""
    print(
        f"[{time.perf_counter() - START:7.1f} s] {message}", file=sys.stderr, flush=True
    )


# ----------------------------------------------------------------- machine, versions


def cpu_model() -> str:
    try:
        with open("/proc/cpuinfo") as file:
            for line in file:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine() or "unknown"


def package_version(name: str) -> str | None:
    """The installed version of `name`; else its `__version__` if it is imported
    (a source tree on `sys.path`); else None."""
    try:
        return importlib.metadata.version(name)
    except importlib.metadata.PackageNotFoundError:
        return getattr(sys.modules.get(name), "__version__", None)


def versions(*extra: str) -> dict[str, str | None]:
    """jaxhyst, jax, jaxlib, numpy, equinox, optimistix and `extra` -> version."""
    return {name: package_version(name) for name in (*CORE_PACKAGES, *extra)}


def machine_info(*extra: str, devices: bool = True, load: bool = False) -> dict:
    """The date, CPU, platform, Python and package versions (`extra` beside the core
    ones); with `devices`, JAX's devices and whether x64 is on (this imports JAX);
    with `load`, the load average now."""
    info: dict[str, Any] = {
        "date": datetime.now().astimezone().isoformat(timespec="seconds"),
        "cpu_count": os.cpu_count(),
        "cpu_model": cpu_model(),
        "platform": platform.platform(),
        "python": platform.python_version(),
        "versions": versions(*extra),
    }
    if load:
        info["load_average"] = os.getloadavg()
    if devices:
        import jax

        info["devices"] = [str(d) for d in jax.devices()]
        info["x64"] = bool(jax.config.read("jax_enable_x64"))
    return info


def machine_lines(info: dict) -> list[str]:
    """`machine: ...` and `versions: ...` lines for `machine_info`'s dict (older
    results without the date or the devices read as well)."""
    parts = [
        f"{info['cpu_count']} CPUs ({info['cpu_model']})",
        info["platform"],
        f"Python {info['python']}",
    ]
    if info.get("devices"):
        parts.append(f"devices {', '.join(info['devices'])}")
    date = f"; {info['date']}" if info.get("date") else ""
    installed = ", ".join(
        f"{name} {version or 'not installed'}"
        for name, version in info["versions"].items()
    )
    return [f"machine: {', '.join(parts)}{date}", f"versions: {installed}"]


def print_machine(info: dict) -> None:
    for line in machine_lines(info):
        print(line)


# --------------------------------------------------------------------------- options


def add_json(parser: argparse.ArgumentParser, text: str = "write the results as JSON"):
    parser.add_argument("--json", metavar="PATH", help=text)


def add_force(parser: argparse.ArgumentParser):
    parser.add_argument("--force", action="store_true", help="replace existing outputs")


def add_data_dir(parser: argparse.ArgumentParser, holding: str):
    parser.add_argument(
        "--data-dir",
        default=None,
        help=f"data directory holding {holding} (default: {DATA_DIR_DEFAULT})",
    )


def data_dir(value: str | None) -> Path:
    """`--data-dir`, or jaxhyst's default data directory when it is not given."""
    if value is not None:
        return Path(value)
    import jaxhyst as jh

    return jh.datasets.default_data_dir()


def add_figures(parser: argparse.ArgumentParser, out: str):
    """`--out DIR` (default `out`) and `--no-figures`."""
    parser.add_argument(
        "--out", default=out, help="folder for the figures (created if missing)"
    )
    parser.add_argument("--no-figures", action="store_true", help="skip the figures")


def add_record_options(parser: argparse.ArgumentParser, holding: str, out: str):
    """--data-dir, --seed, --out, --no-figures and --json of the scripts on measured
    records."""
    add_data_dir(parser, holding)
    parser.add_argument("--seed", type=int, default=0, help="swarm seed")
    add_figures(parser, out)
    add_json(parser)


def open_data(args: argparse.Namespace) -> Path:
    """`add_record_options`'s data directory; first checks that the figures can be
    drawn (unless --no-figures), so that a run does not fail at its end."""
    folder = data_dir(args.data_dir)
    if not args.no_figures:
        require_matplotlib()
    log(f"data: {folder}")
    return folder


def require_matplotlib(
    what: str = "the figures need", hint: str = "; or pass --no-figures"
):
    """Exit with a message now, rather than after the run, if matplotlib is missing."""
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        raise SystemExit(
            f"{script_name()}: {what} matplotlib (pip install 'jaxhyst[plot]'){hint}."
        ) from None


# ----------------------------------------------------------------------- JSON, files


def jsonable(value):
    """Strict JSON of results (arrays and NumPy/JAX scalars -> lists and numbers,
    tuples -> lists, non-finite numbers -> None): the package's one serialiser."""
    from jaxhyst._serialise import jsonable as strict

    return strict(value)


def write_json(data, path) -> Path:
    """Write `data` as the package writes JSON (strict, indented) to `path` (its
    folder created) and say so on stdout."""
    from jaxhyst._serialise import dumps

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(dumps(data) + "\n")
    print(f"wrote {path}")
    return path


def write_results(path, **fields) -> None:
    """If `path` is given, write `fields` and the machine (`machine_info()`) there."""
    if path:
        write_json({**fields, "machine": machine_info()}, path)


def output_paths(
    json_path=None,
    folder=None,
    names=(),
    *,
    force: bool = False,
    folder_option: str = "--out",
) -> list[Path]:
    """The files a run will write (the JSON, and `names` in `folder`); exits before
    the run if one exists and `force` is not set, or if `folder` is a file."""
    paths = [Path(json_path)] if json_path else []
    if folder:
        folder = Path(folder)
        if folder.exists() and not folder.is_dir():
            raise SystemExit(
                f"{script_name()}: {folder_option} {folder} is a file, not a folder"
            )
        paths += [folder / name for name in names]
    existing = [str(path) for path in paths if path.exists()]
    if existing and not force:
        raise SystemExit(
            f"{script_name()}: {', '.join(existing)} already exist(s); pass --force to "
            "replace them"
        )
    return paths


class FigureWriter:
    """Figures (one column of panels) saved as PNG files into `folder` (created),
    the paths kept in `written`."""

    def __init__(self, folder, dpi: int = 130):
        self.folder = Path(folder)
        self.folder.mkdir(parents=True, exist_ok=True)
        self.dpi = dpi
        self.written: list[str] = []

    def new(self, rows: int, height: float, width: float = 8.0):
        """A figure and its `rows` axes."""
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure

        figure = Figure(figsize=(width, height), layout="constrained")
        FigureCanvasAgg(figure)
        return figure, figure.subplots(rows, 1, squeeze=False)[:, 0]

    def save(self, figure, name: str) -> None:
        path = self.folder / name
        figure.savefig(path, dpi=self.dpi)
        self.written.append(str(path))


# ------------------------------------------------------------------------- diagnosis


def screened(summary: dict) -> list[dict]:
    """Every candidate of `Diagnosis.to_dict()["candidates"]`, round by round: its
    score statistic, whether it was significant and passed held-out validation, and
    why it was not adopted (`rejected`: the diagnosis's reason, e.g. "the refitted
    model diverged")."""
    rows = []
    for index, round_ in enumerate(summary["candidates"]):
        for c in round_:
            validation = c.get("validation", {})
            rows.append(
                {
                    "round": index + 1,
                    "effect": c["effect"],
                    "statistic": float(c["statistic"]),
                    "dof": int(c["dof"]),
                    "significant": bool(c["significant"]),
                    "accepted": bool(validation.get("accepted", False)),
                    "heldout_rmse_before": validation.get("heldout_rmse_before"),
                    "heldout_rmse_after": validation.get("heldout_rmse_after"),
                    "rejected": c.get("rejected"),
                }
            )
    return rows


def diagnose(recording, seed: int) -> dict:
    """`jh.diagnose(recording)` with the key of `seed`, timed: the recording and the
    diagnosis ("recording", "result": objects, see `without_objects`) and what the
    scripts report of it."""
    import jax

    import jaxhyst as jh

    start = time.perf_counter()
    result = jh.diagnose(recording, key=jax.random.key(seed))
    seconds = time.perf_counter() - start
    summary = result.to_dict()
    return {
        "recording": recording,
        "result": result,
        "seconds": seconds,
        "samples": recording.num_samples,
        "rate_hz": recording.sample_rate,
        "effects": list(result.effects),
        "baseline": {k: float(v) for k, v in result.baseline.items()},
        "final": {k: float(v) for k, v in result.final.items()},
        "findings": summary["findings"],
        "final_parameters": summary["final"]["parameters"],
        "ambiguities": summary["ambiguities"],
        "undecided": summary["undecided"],
        "advice": summary["advice"],
        "steps": summary["steps"],
        "remainder": summary["remainder"],
        "location": summary["location"],
        "screened": screened(summary),
    }


def without_objects(diagnosis: dict) -> dict:
    """`diagnose`'s dict without the recording and the diagnosis object (for JSON)."""
    return {k: v for k, v in diagnosis.items() if k not in ("recording", "result")}


# ------------------------------------------------------- synthetic suites (diagnosis)


def case_keys(root: int, index: int):
    """(generation key, diagnosis key) of case `index` under the root seed."""
    import jax

    key = jax.random.fold_in(jax.random.key(root), index)
    return jax.random.split(key)


def effects_label(effects, none: str = "clean") -> str:
    return "+".join(effects) if effects else none


def add_suite_options(
    parser: argparse.ArgumentParser,
    quick: str,
    *,
    cases: int | None = None,
    only_example: str | None = None,
    generates: str = "the suite and print it",
):
    """--cases (default `cases`; None: 3, or 1 with --quick), --quick (`quick`: what
    it runs), --json, --seed, --dry-run, --progress and (with `only_example`) --only
    of the synthetic suites, and the batch's --workers and --out."""
    parser.add_argument(
        "--cases",
        type=int,
        default=cases,
        help=f"seeds per configuration (default {3 if cases is None else cases})",
    )
    parser.add_argument("--quick", action="store_true", help=f"smoke run: {quick}")
    add_json(parser, "write the results here")
    parser.add_argument("--seed", type=int, default=0, help="root seed (0)")
    parser.add_argument(
        "--dry-run",
        action="store_true",
        help=f"generate {generates}, without diagnosing",
    )
    parser.add_argument(
        "--progress",
        action="store_true",
        help="show the batch's progress line (each record's own progress goes to "
        "its log.txt)",
    )
    add_batch_options(parser)
    if only_example is not None:
        parser.add_argument(
            "--only",
            nargs="+",
            metavar="LABEL",
            help=f"run only these configurations (e.g. {only_example}); each keeps "
            "the index, so the seed, it has in the whole suite",
        )


def selected(specs: list[dict], only) -> Iterator[tuple[int, dict]]:
    """(index, spec) of the cases `--only` keeps (every case without it); the index
    is the case's place in the whole suite, so it keeps its seed."""
    for index, spec in enumerate(specs):
        if not only or effects_label(spec["effects"]) in only:
            yield index, spec


def case_record(index: int, spec: dict, case, generated: float, **extra) -> dict:
    """What a suite records of a generated case (`extra` after its noise)."""
    return {
        "index": index,
        "effects": list(case.effects),
        "noise": case.noise,
        **extra,
        "seed": spec["seed"],
        "sigma": case.sigma,
        "sizes": case.sizes,
        "truth": case.truth_description,
        "generate_seconds": generated,
    }


def diagnosed(case, diagnosis: "BatchDiagnosis") -> dict:
    """What every suite records of the batch's diagnosis of `case`: the named
    effects, exact or not, the final residual, the diagnosis's own seconds and the
    record's on its worker, what it reports as unexplained."""
    data = diagnosis.json
    named = [str(f["effect"]) for f in data["findings"]]
    final = float(data["final"]["rmse"])
    return {
        "named": named,
        "exact": set(named) == set(case.effects),
        "final_rmse": final,
        "final_over_sigma": final / case.sigma,
        "seconds": diagnosis.seconds,
        "wall_seconds": diagnosis.wall_seconds,
        "unexplained": [u["description"] for u in data["unexplained"]],
    }


def verdict(r: dict, width: int) -> str:
    """The end of a diagnosed case's progress line: ok or MISS, named, final."""
    named = "+".join(r["named"]) or "none"
    mark = "ok " if r["exact"] else "MISS"
    left = len(r.get("unexplained", []))
    return (
        f" | {mark} named {named:<{width}} final {r['final_over_sigma']:.2f} sigma "
        f"{r['seconds']:.1f}s" + (f" unexplained {left}" if left else "")
    )


def suite_report(config: dict, environment: dict, results: list[dict]) -> dict:
    """The JSON report of a suite: its settings, the machine, the cases."""
    return {
        "config": config,
        "environment": environment,
        "generate_median_seconds": statistics.median(
            r["generate_seconds"] for r in results
        ),
        "cases": results,
    }


def finish_suite(report: dict, json_path: str | None, note: str = "") -> int:
    """The median generation time, the JSON report if asked for; exit status 0."""
    print(
        f"median generation seconds per recording: "
        f"{report['generate_median_seconds']:.2f}{note}"
    )
    if json_path:
        write_json(report, json_path)
    return 0


def mean_or_nan(values) -> float:
    import numpy as np

    return float(np.mean(values)) if values else math.nan


def median_or_nan(values) -> float:
    import numpy as np

    return float(np.median(values)) if values else math.nan


def confusion(results, effects) -> tuple[list[str], list[str], list[list[int]]]:
    """Rows the true effect (a pair counts in both rows; "none" for clean records),
    columns the named effect ("none" when nothing was named)."""
    rows = [*effects, "none"]
    named = {n for r in results for n in r["named"]}
    columns = [*effects, *sorted(named - set(effects)), "none"]
    counts: Counter = Counter()
    for r in results:
        truth = r["effects"] or ["none"]
        guesses = r["named"] or ["none"]
        for t in truth:
            for g in guesses:
                counts[t, g] += 1
    return rows, columns, [[counts[r, c] for c in columns] for r in rows]


def print_confusion(matrix: dict, width: int) -> None:
    """`score_suite`'s confusion matrix, columns `width` characters wide."""
    rows, columns = matrix["rows"], matrix["columns"]
    short = [c[:width] for c in columns]
    first = max(len(r) for r in rows) + 2
    print("confusion (rows: true effect, columns: named effect)")
    print(" " * first + " ".join(f"{c:>{width}}" for c in short))
    for row, counts in zip(rows, matrix["counts"]):
        print(f"{row:<{first}}" + " ".join(f"{n:>{width}d}" for n in counts))


def score_suite(
    report: dict, effects, residual_factor: float, *, effect_cases_only: bool
) -> dict:
    """The suite's summary and confusion matrix, stored in `report` (whose "cases"
    are diagnosed); the residual fraction counts the effect cases only or all."""
    results = report["cases"]
    effect_cases = [r for r in results if r["effects"]]
    clean_cases = [r for r in results if not r["effects"]]
    final_cases = effect_cases if effect_cases_only else results
    summary: dict[str, Any] = {
        "cases": len(results),
        "exact_set_accuracy": mean_or_nan([r["exact"] for r in effect_cases]),
        "true_effect_recall": mean_or_nan(
            [e in r["named"] for r in effect_cases for e in r["effects"]]
        ),
        "clean_no_finding_rate": mean_or_nan([not r["named"] for r in clean_cases]),
        "final_within_1.3_sigma": mean_or_nan(
            [r["final_over_sigma"] <= residual_factor for r in final_cases]
        ),
        "median_final_over_sigma": median_or_nan(
            [r["final_over_sigma"] for r in results]
        ),
        "median_seconds": statistics.median(r["seconds"] for r in results),
        # The bars' "median per record" counts every record; these say how far the
        # clean records (which stop early) pull it down.
        "median_seconds_effect_cases": median_or_nan(
            [r["seconds"] for r in effect_cases]
        ),
        "median_seconds_clean_cases": median_or_nan(
            [r["seconds"] for r in clean_cases]
        ),
        "by_configuration": {},
    }
    groups: dict[str, list] = {}
    for r in results:
        groups.setdefault(f"{effects_label(r['effects'])} / {r['noise']}", []).append(r)
    for name, group in groups.items():
        summary["by_configuration"][name] = {
            "cases": len(group),
            "exact": mean_or_nan([r["exact"] for r in group]),
            "median_final_over_sigma": median_or_nan(
                [r["final_over_sigma"] for r in group]
            ),
        }
    rows, columns, table = confusion(results, effects)
    report["summary"] = summary
    report["confusion"] = {"rows": rows, "columns": columns, "counts": table}
    return summary


def print_summary(
    summary: dict, report: dict, residual_factor: float, *, width: int, over: str
) -> None:
    """`score_suite`'s figures and confusion matrix, as every suite prints them
    (`over`: the cases the residual fraction counts, e.g. "effect cases")."""
    print()
    print(f"exact-set accuracy (effect cases): {summary['exact_set_accuracy']:.1%}")
    for protocol, part in summary.get("by_protocol", {}).items():
        print(f"  {protocol:<10} {part['exact']:.1%} of {part['effect_cases']}")
    print(f"true-effect recall:                {summary['true_effect_recall']:.1%}")
    print(f"clean cases with no finding:       {summary['clean_no_finding_rate']:.1%}")
    print(
        f"final residual <= {residual_factor} sigma ({over}): "
        f"{summary['final_within_1.3_sigma']:.1%} "
        f"(median {summary['median_final_over_sigma']:.2f} sigma, all cases)"
    )
    print(
        f"median seconds per recording:      {summary['median_seconds']:.1f} "
        f"(effect cases {summary['median_seconds_effect_cases']:.1f}, "
        f"clean {summary['median_seconds_clean_cases']:.1f})"
    )
    print()
    print_confusion(report["confusion"], width=width)


def case_line(
    index: int, total: int, r: dict, *, width: int, sizes_width: int, extra: str = ""
) -> str:
    """A suite's progress line for case `r`: its place, effects, noise (and `extra`),
    the sizes reached (with the truth's form where the suite records forms), the
    generation time and, once diagnosed, the verdict."""
    forms = r.get("forms", {})
    sizes = (
        ", ".join(
            f"{k} {v:.1f}" + (f" {forms[k]}" if k in forms else "")
            for k, v in r["sizes"].items()
        )
        or "-"
    )
    line = (
        f"[{index + 1:3d}/{total}] {effects_label(r['effects']):<{width}} "
        f"{r['noise']:<8} {extra}sizes(sigma): {sizes:<{sizes_width}} "
        f"gen {r['generate_seconds']:.1f}s"
    )
    return line + verdict(r, width) if "named" in r else line


def suite_config(args: argparse.Namespace, **extra) -> dict:
    """The settings every suite records (seeds per configuration, root seed, quick,
    dry run, batch workers) and the suite's own."""
    return {
        "cases_per_configuration": args.cases,
        **extra,
        "seed": args.seed,
        "quick": args.quick,
        "dry_run": args.dry_run,
        "workers": args.workers,
    }


# ---------------------------------------------------- the suites' batch of diagnoses


def _workers(text: str) -> int:
    count = int(text)
    if count < 1:
        raise argparse.ArgumentTypeError(f"{text}: pass 1 or more")
    return count


def add_batch_options(parser: argparse.ArgumentParser) -> None:
    """--workers and --out of the suites that diagnose their records in a batch."""
    parser.add_argument(
        "--workers",
        type=_workers,
        default=2,
        metavar="N",
        help="batch workers, one thread each (2)",
    )
    parser.add_argument(
        "--out",
        default=None,
        metavar="DIR",
        help="keep the batch folder here: recordings/, manifest.csv, records/NAME/ "
        "(each diagnosis's JSON, report and log), summary.csv; a rerun on DIR skips "
        "the records already done (default: a temporary folder, deleted)",
    )


class BatchRecord(NamedTuple):
    """A recording to diagnose in a batch: its `name` (file stem and record folder),
    the `recording`, the diagnosis `key` (a threefry key, as `jax.random.key`
    makes) and `labels` (columns of the manifest and the summary)."""

    name: str
    recording: Any
    key: Any
    labels: dict[str, str]


class BatchDiagnosis(NamedTuple):
    """A record's diagnosis from the batch: `json` as `jaxhyst diagnose --json`
    writes it, `seconds` the diagnosis's own time (its `timing.total_s`: what
    `Diagnosis.seconds` was in the suites' earlier in-process runs) and
    `wall_seconds` the record's time on its worker (the summary's `seconds`: reading
    the file, the diagnosis, its JSON and report)."""

    json: dict
    seconds: float
    wall_seconds: float


def key_seed(key) -> int:
    """The `--seed` whose key is `key`. The command line's key of a seed is
    `jax.random.key(seed)`, which (64-bit JAX, the threefry generator) holds the
    seed's 64 bits as two 32-bit words, so every threefry key is some seed's."""
    import jax
    import numpy as np

    data = np.asarray(jax.random.key_data(key))
    high, low = (int(word) for word in data.reshape(-1))
    bits = high << 32 | low
    seed = bits - 2**64 if bits >= 2**63 else bits
    if not np.array_equal(jax.random.key_data(jax.random.key(seed)), data):
        raise ValueError(
            f"{script_name()}: key {data} is no seed's key (64-bit JAX and the "
            "threefry generator are needed)"
        )
    return seed


def diagnose_batch(
    records: list[BatchRecord], options: dict[str, str], args: argparse.Namespace
) -> list[BatchDiagnosis]:
    """Diagnose `records` as `jaxhyst diagnose` does, in one `jh.batch` on
    `args.workers` workers of one thread, in `args.out` (else a temporary folder):
    each recording as a CSV file under `recordings/` (written to every bit), a
    manifest (command diagnose, the recording's columns, the seed of its key,
    `options` such as {"model": "bouc-wen"}, its labels); returns each record's
    diagnosis, in order. Exits naming the records that failed."""
    import tempfile

    if args.out is not None:
        return _diagnose_in(Path(args.out), records, options, args)
    with tempfile.TemporaryDirectory(prefix=f"{script_name()}-") as folder:
        return _diagnose_in(Path(folder), records, options, args)


def diagnose_suite(
    args: argparse.Namespace, model: str, generated: list[tuple[dict, Any, Any]]
) -> list[BatchDiagnosis]:
    """A synthetic suite's `generated` cases, (record, case, diagnosis key) each,
    diagnosed by `diagnose --model MODEL` in one batch (nothing on --dry-run): each
    record updated with `diagnosed`; returns the diagnoses in order."""
    if args.dry_run:
        return []
    records = [
        BatchRecord(
            f"{r['index']:03d}_{effects_label(case.effects)}_{case.noise}",
            case.recording,
            key,
            {"truth": effects_label(case.effects, none=""), "noise": case.noise},
        )
        for r, case, key in generated
    ]
    diagnoses = diagnose_batch(records, {"model": model}, args)
    for (r, case, _), diagnosis in zip(generated, diagnoses, strict=True):
        r.update(diagnosed(case, diagnosis))
    return diagnoses


def _columns(recording) -> dict[str, str]:
    """The manifest cells that read `recording`'s saved columns back."""
    names = (*recording.input_names, recording.output_name)
    for name in names:
        if not name or any(c.isspace() or c == ";" for c in name):
            raise ValueError(
                f"{script_name()}: column {name!r} of {recording.name!r}: a manifest "
                "cell cannot name it (spaces and semicolons separate inputs)"
            )
    return {"input": " ".join(recording.input_names), "output": recording.output_name}


def _diagnose_in(
    folder: Path,
    records: list[BatchRecord],
    options: dict[str, str],
    args: argparse.Namespace,
) -> list[BatchDiagnosis]:
    import csv
    import json

    import jaxhyst as jh
    from jaxhyst._batch._store import record_folder
    from jaxhyst._batch._task import RESULT

    (folder / "recordings").mkdir(parents=True, exist_ok=True)
    rows = []
    for record in records:
        path = folder / "recordings" / f"{record.name}.csv"
        record.recording.save(path, overwrite=True)
        rows.append(
            {
                "recording": path.relative_to(folder).as_posix(),
                "command": "diagnose",
                "name": record.name,
                **_columns(record.recording),
                "seed": str(key_seed(record.key)),
                **options,
                **record.labels,
            }
        )
    header = list(dict.fromkeys(column for row in rows for column in row))
    manifest = folder / "manifest.csv"
    with open(manifest, "w", newline="") as file:
        writer = csv.DictWriter(file, header, restval="")
        writer.writeheader()
        writer.writerows(rows)
    log(f"batch: {len(records)} records on {args.workers} workers in {folder}")
    start = time.perf_counter()
    result = jh.batch(
        manifest,
        folder,
        cluster=jh.LocalWorkers(args.workers, 1),
        progress=args.progress,
    )
    log(f"batch: done in {time.perf_counter() - start:.1f} s")
    failed = [row for row in result.rows if row.status != "done"]
    if failed:
        kept = "" if args.out else " (pass --out DIR to keep the records' logs)"
        raise SystemExit(
            f"{script_name()}: {len(failed)} of {len(result.rows)} records failed"
            f"{kept}:\n"
            + "\n".join(f"  {row.record.name}: {row.error}" for row in failed)
        )
    out = []
    for row in result.rows:
        data = json.loads((record_folder(folder, row.record.name) / RESULT).read_text())
        out.append(
            BatchDiagnosis(
                json=data,
                seconds=float(data["timing"]["total_s"]),
                wall_seconds=float(row.seconds or math.nan),
            )
        )
    return out
