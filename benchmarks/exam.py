"""Benchmark: the exam (issue 51, item 6), records the engine is never tuned to.

Per family at least 40 synthetic records whose truth forms are in no catalogue, in
no `jaxhyst.synthetic` generator and not among the forms planned for the engine
(`_exam_truth.py` gives each form's equation): every effect alone in two exam forms,
pairs that real specimens show, and clean records; white and coloured noise.

- piezo: single sines of one frequency (0.5-10 Hz, 10 s at 1 kHz), from rest or
  switched on from rest after a hold;
- structural: quasi-static tests of 2000 points (pseudo time = sample index): a
  FEMA 461-like ladder (x1.3-1.5 per level, 2-3 cycles each), a CUREE-like ladder
  (a primary cycle then trailing cycles at 75 %), an earthquake-like history;
- damper: 5 s at 3004.8 Hz, a random displacement under a random piecewise-constant
  command (as the damper suite) or two sines under a command staircase.

Each effect's size is the RMS of the change it makes, alone, that a refit of the
base cannot take up (to first order: the change less its least-squares projection
on the base's output sensitivities; on one sine most of a rate-dependent amplitude
or a lagged hysteresis is a different base), drawn log-uniformly in [4, 15] noise
sigmas per record; the raw change is at most 60 sigmas and each form's parameters
stay physical. A form that reaches neither its size nor 90 % of 4 sigmas gives way
to the effect's other form if that comes closer; `sizes` says what was reached
(the dry run prints it; below 4 sigmas the record is small, not wrong). A driver
lag is sized on top of its field dependence, drawn in [15, 40] sigmas (a lag shows
only a share of the field's effect). The noise sigma is 0.05-0.2 % of the output
range (piezo), 0.6-1.5 % (structural) or 0.5-1.5 % (damper) of the peak force;
coloured noise is AR(1) (0.85-0.97 piezo, 0.5-0.9 otherwise). Everything follows
from --seed. The records are written as CSV files (checked to read back
bit-identical) with their truth (`recordings/NAME.json`) and a manifest
(`command` diagnose, `model`, `input`, `output`, `seed`; labels `family`, `truth`,
`forms`, `sigma`, `noise`, `protocol`, `sizes`, `visible`, `confirmable`), and
diagnosed by `jh.batch` on `LocalWorkers(--workers, 1)`; a rerun on the same
--out reuses the recordings this code made and the batch skips the records done.

Scoring, per family (the issue's bars in brackets):
- exact sets: the named set equals the truth, over effect records [>= 85 %];
- false claims: named effects not in the truth, each counted, except on a record
  whose diagnosis JSON's `undecided` (the union of the effects its ambiguities
  leave open: "cannot tell X from Y", "cannot tell whether X is present", "X may
  also be present") holds a truth effect: an ambiguity that names the truth
  excuses the claim; statements of decisions ("X was adopted, then dropped",
  "replaced by") leave nothing open and excuse nothing; on a clean record every
  named effect is a false claim [<= 1 per 40 records]; `strict` counts every
  named effect not in the truth;
- clean records silent: nothing named [all];
- final RMS <= 1.3 sigma on the effect records whose truth the held-out design can
  confirm: the truth's visible change (all its effects together, as sized) is at
  least 1 sigma, so that a base fit alone leaves more than sqrt(2) sigma and the
  held-out blocks see the difference [>= 85 %]; sigma is the true marginal noise
  standard deviation;
- the median seconds per record (the diagnosis's own `timing.total_s`) and a
  confusion table (rows: true effects, a pair counting in both; columns: named).
A record the batch did not diagnose fails every bar it counts in.

Do not tune the engine to these records: change it, then run the exam.

    python benchmarks/exam.py --dry-run                   # generate, print sizes
    python benchmarks/exam.py --family piezo --limit 1    # one record: a smoke run
    python benchmarks/exam.py --out exam-runs --json exam.json   # the whole exam
    python benchmarks/exam.py --score-only exam-runs
"""

import argparse
import csv
import functools
import hashlib
import json
import math
import statistics
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

import jax


jax.config.update("jax_enable_x64", True)

import _common as common  # noqa: E402
import _exam_truth as truth  # noqa: E402
import numpy as np  # noqa: E402

import jaxhyst as jh  # noqa: E402
from jaxhyst._batch import read_manifest  # noqa: E402


FAMILIES = ("piezo", "structural", "damper")
# The generator's own fingerprint: a rerun on an --out folder reuses a recording only
# if this code made it (else it is made again; the batch skips it if it came out
# the same, byte for byte).
GENERATOR = hashlib.sha256(
    b"".join(
        (Path(__file__).parent / n).read_bytes() for n in ("exam.py", "_exam_truth.py")
    )
).hexdigest()[:12]
MODEL = {"piezo": "piezo", "structural": "bouc-wen", "damper": "mr-damper"}
SIZES = (4.0, 15.0)  # noise sigmas, log-uniform
# The field dependence a driver lag is seen through is drawn larger: a lag shows
# only a share of the field's effect (real MR dampers' field effects are far larger).
HOST_SIZES = (15.0, 40.0)
CONFIRMABLE = 1.0  # visible sigmas: the held-out blocks can confirm the truth
FINAL_BAR = 1.3  # final RMS / sigma
BARS = {"exact": 0.85, "false_per_40": 1.0, "final": 0.85}

PIEZO_PAIRS = (
    ("creep", "drift"),
    ("asymmetry", "rate_dependence"),
    ("input_bias", "creep"),
    ("asymmetry", "dynamics"),
)
STRUCTURAL_PAIRS = (
    ("degradation", "pinching"),
    ("degradation", "asymmetry"),
    ("pinching", "drift"),
    ("degradation", "drift"),
)
DAMPER_PAIRS = (
    ("field_dependence", "rolloff"),
    ("field_dependence", "asymmetry"),
    ("field_dependence", "offset"),
)


# ------------------------------------------------------------------------ the plan


def _plan(family: str) -> list[dict]:
    """The family's records in a fixed order: (effects, preferred forms, protocol,
    noise). Effects are in catalogue order."""
    forms = truth.FORMS[family]
    rows: list[dict] = []

    def add(effects, preferred, protocol, noise):
        order = list(forms)
        effects = tuple(sorted(effects, key=order.index))
        rows.append(
            {
                "effects": effects,
                "preferred": preferred,
                "protocol": protocol,
                "noise": noise,
            }
        )

    noises = ("white", "coloured")
    if family == "piezo":
        for effect, pair in forms.items():
            for k, form in enumerate(pair):
                for j, protocol in enumerate(("sine", "switch-on")):
                    add((effect,), {effect: form}, protocol, noises[(k + j) % 2])
        for pair in PIEZO_PAIRS:
            for j, protocol in enumerate(("sine", "switch-on")):
                add(pair, {}, protocol, noises[j])
        for j in range(8):
            add((), {}, ("sine", "switch-on")[j // 2 % 2], noises[j % 2])
    elif family == "structural":
        protocols = ("ladder", "curee", "earthquake")
        for effect, pair in forms.items():
            for k, form in enumerate(pair):
                for j, protocol in enumerate(protocols):
                    add((effect,), {effect: form}, protocol, noises[(k + j) % 2])
        for pair in STRUCTURAL_PAIRS:
            for j, protocol in enumerate(("ladder", "earthquake")):
                add(pair, {}, protocol, noises[j])
        for j in range(8):
            add((), {}, protocols[j % 3], noises[j // 3 % 2 if j < 6 else j % 2])
    else:
        protocols = ("random", "sine-steps", "random")
        field = truth.DAMPER_FORMS["field_dependence"]
        for effect, pair in forms.items():
            for k, form in enumerate(pair):
                for j, protocol in enumerate(protocols):
                    noise = noises[(k + j) % 2]
                    if effect == "driver_lag":
                        preferred = {effect: form, "field_dependence": field[j % 2]}
                        add(("field_dependence", effect), preferred, protocol, noise)
                    else:
                        add((effect,), {effect: form}, protocol, noise)
        for pair in DAMPER_PAIRS:
            for j, protocol in enumerate(("random", "sine-steps")):
                add(pair, {}, protocol, noises[j])
        for j in range(6):
            add((), {}, protocols[j % 2], noises[j // 2 % 2])
    for index, row in enumerate(rows):
        label = "+".join(row["effects"]) or "clean"
        row["index"] = index
        row["name"] = f"{family}-{index:02d}-{label}"
    return rows


def _rng(seed: int, family: str, index: int, part: str) -> np.random.Generator:
    parts = ("base", "input", "forms", "sizes", "effects", "noise")
    words = [seed, FAMILIES.index(family), index, parts.index(part)]
    return np.random.default_rng(words)


def _key(seed: int, family: str, index: int):
    root = jax.random.fold_in(jax.random.key(seed), FAMILIES.index(family))
    return jax.random.fold_in(root, index)


# ------------------------------------------------------------------- excitations


def piezo_drive(
    rng, protocol: str, effects
) -> tuple[np.ndarray, np.ndarray, float, str]:
    """(t, u in V, frequency, words): one sine of 10 s at 1 kHz from rest at 0 V, or
    a hold at 0 V, a rise to mid-level and the sine from there."""
    rate, duration = 1000.0, 10.0
    t = np.arange(int(round(duration * rate)) + 1) / rate
    low = 2.0 if "dynamics" in effects else 0.5  # a stage mode needs some speed
    f = truth.loguniform(rng, low, 10.0)
    amp = rng.uniform(35.0, 50.0)
    if protocol == "sine":
        u = amp - amp * np.cos(2 * np.pi * f * t)
        return t, u, f, f"sine {f:.3g} Hz, 0..{2 * amp:.3g} V from rest"
    hold, rise = rng.uniform(1.0, 3.0), rng.uniform(0.01, 0.03)
    running = t - hold - rise
    u = np.where(
        t < hold,
        0.0,
        np.where(
            running < 0,
            amp * (t - hold) / rise,
            amp + amp * np.sin(2 * np.pi * f * running),
        ),
    )
    words = (
        f"hold 0 V {hold:.3g} s, rise to {amp:.3g} V in {1e3 * rise:.3g} ms, sine "
        f"{f:.3g} Hz 0..{2 * amp:.3g} V"
    )
    return t, u, f, words


def _sample_path(vertices: np.ndarray, points: int) -> np.ndarray:
    """`points` samples along the turning points `vertices` with nearly equal
    displacement steps, every turning point a sample (a test controller's)."""
    vertices = np.asarray(vertices, float)
    vertices = vertices[np.concatenate([[True], np.abs(np.diff(vertices)) > 0])]
    lengths = np.abs(np.diff(vertices))
    steps = points - 1
    raw = lengths / lengths.sum() * steps
    counts = np.maximum(np.floor(raw).astype(int), 1)
    while counts.sum() < steps:
        counts[np.argmax(raw - counts)] += 1
    while counts.sum() > steps:
        counts[np.argmax(np.where(counts > 1, counts - raw, -np.inf))] -= 1
    pieces = [vertices[:1]]
    for a, b, n in zip(vertices[:-1], vertices[1:], counts):
        pieces.append(np.linspace(a, b, n + 1)[1:])
    return np.concatenate(pieces)


def structural_protocol(rng, protocol: str, x_y: float, points: int = 2000):
    """(x in mm, words): an imposed-displacement history of `points` samples."""
    sign = float(rng.choice([1.0, -1.0]))
    if protocol == "ladder":
        first, growth = rng.uniform(0.2, 0.4), rng.uniform(1.3, 1.5)
        last, cycles = rng.uniform(4.0, 7.0), int(rng.choice([2, 3]))
        levels = [first]
        while levels[-1] < last:
            levels.append(levels[-1] * growth)
        vertices = [0.0]
        for a in levels:
            vertices += [sign * a * x_y, -sign * a * x_y] * cycles
        words = (
            f"FEMA 461-like ladder, {len(levels)} levels x {cycles} cycles, "
            f"{first:.2g}-{levels[-1]:.2g} x_y (x{growth:.2g})"
        )
    elif protocol == "curee":
        reference = rng.uniform(2.5, 3.5) * x_y
        steps = ((0.1, 0, 3), (0.2, 1, 3), (0.3, 1, 2), (0.4, 1, 2), (0.7, 1, 2))
        steps += ((1.0, 1, 2), (1.5, 1, 2), (2.0, 1, 2))
        vertices = [0.0]
        for share, primary, trailing in steps:
            a = share * reference
            vertices += [sign * a, -sign * a] * primary
            vertices += [0.75 * sign * a, -0.75 * sign * a] * trailing
        words = f"CUREE-like, reference {reference / x_y:.2g} x_y, to {2 * reference / x_y:.2g} x_y"
    else:
        dense = np.linspace(0.0, 1.0, 4096)
        f = rng.uniform(6.0, 40.0, 30)
        phase = rng.uniform(0, 2 * np.pi, 30)
        signal = np.sum(
            f[:, None] ** -1.5
            * np.sin(2 * np.pi * f[:, None] * dense + phase[:, None]),
            axis=0,
        )
        peak_at, a = rng.uniform(0.2, 0.35), rng.uniform(1.5, 3.0)
        envelope = (dense / peak_at) ** a * np.exp(a * (1 - dense / peak_at))
        x = signal * envelope
        x *= rng.uniform(3.0, 6.0) * x_y / np.max(np.abs(x))
        slope = np.diff(x)
        turns = np.flatnonzero(np.sign(slope[1:]) != np.sign(slope[:-1])) + 1
        vertices = np.concatenate([[0.0], x[turns]])
        words = (
            f"earthquake-like (Saragoni-Hart envelope, 30 components 6-40 cycles, "
            f"peak {np.max(np.abs(x)) / x_y:.2g} x_y, {len(vertices)} turning points)"
        )
    vertices = np.append(np.asarray(vertices, float), 0.0)
    return _sample_path(vertices, points), words


def damper_drive(rng, protocol: str):
    """(t, x in cm, command in V, words): 5 s at 3004.8 Hz."""
    rate, duration = 3004.8, 5.0
    count = int(round(duration * rate)) + 1
    t = np.arange(count) / rate
    peak = rng.uniform(0.5, 1.2)
    if protocol == "random":
        top = rng.uniform(12.0, 30.0)
        freqs = np.fft.rfftfreq(count, 1 / rate)
        band = (freqs >= 0.3) & (freqs <= top)
        spectrum = np.zeros(freqs.size, complex)
        spectrum[band] = np.exp(2j * np.pi * rng.random(int(band.sum())))
        x = np.fft.irfft(spectrum, count)
        hold = rng.uniform(0.03, 0.1)
        words = f"random 0.3-{top:.3g} Hz, peak {peak:.3g} cm; command held {1e3 * hold:.3g} ms on average"
    else:
        f1, f2 = rng.uniform(1.0, 3.0), rng.uniform(4.0, 10.0)
        ratio = rng.uniform(0.2, 0.6)
        phases = rng.uniform(0, 2 * np.pi, 2)
        x = np.sin(2 * np.pi * f1 * t + phases[0]) + ratio * np.sin(
            2 * np.pi * f2 * t + phases[1]
        )
        ramp = np.clip(t / 0.2, 0, 1)
        x *= 0.5 - 0.5 * np.cos(np.pi * ramp)
        hold = rng.uniform(0.15, 0.5)
        words = f"sines {f1:.3g} + {f2:.3g} Hz, peak {peak:.3g} cm; command staircase of {1e3 * hold:.3g} ms holds"
    x *= peak / np.max(np.abs(x))
    switches = [0.0]
    while switches[-1] < duration:
        length = (
            rng.exponential(hold)
            if protocol == "random"
            else hold * rng.uniform(0.7, 1.3)
        )
        switches.append(switches[-1] + max(0.005, length))
    levels = rng.uniform(0.0, truth.FULL_SCALE, len(switches))
    command = levels[np.searchsorted(np.asarray(switches), t, side="right") - 1]
    return t, x, command, words


def damper_base(rng, x: np.ndarray) -> dict:
    """The damper suite's ranges (N, cm, s): c0 15-40, k0 3-30, f0 within 50, a
    yield force of 100-250 N at z_y log-uniform in [min(3 floor, 0.02), 0.05] cm
    (floor: the family's yield share of the largest step), n 1-2,
    beta/(beta + gamma) 0.5-0.9, A = 1."""
    floor = jh.families.DamperFamily.YIELD_SHARE * float(np.max(np.abs(np.diff(x))))
    c0, k0, f0 = rng.uniform(15, 40), rng.uniform(3, 30), rng.uniform(-50, 50)
    force = rng.uniform(100, 250)
    z_y = truth.loguniform(rng, min(3 * floor, 0.02), 0.05)
    n, ratio = rng.uniform(1, 2), rng.uniform(0.5, 0.9)
    total = z_y**-n
    return {
        "c0": c0,
        "k0": k0,
        "f0": f0,
        "alpha": force / z_y,
        "beta": ratio * total,
        "gamma": (1 - ratio) * total,
        "n": n,
    }


# -------------------------------------------------------------------- generation


def _size_effects(ctx, row, seed, family, sigma):
    """Size each effect alone (the preferred form, else the other one if it comes
    closer); returns the spec, forms, sizes and words."""
    forms_rng = _rng(seed, family, row["index"], "forms")
    sizes_rng = _rng(seed, family, row["index"], "sizes")
    effects_rng = _rng(seed, family, row["index"], "effects")
    spec, forms, sizes, words = {}, {}, {}, []
    ctx.sigma = sigma
    for effect in row["effects"]:
        pair = truth.FORMS[family][effect]
        first = row["preferred"].get(effect) or pair[int(forms_rng.integers(2))]
        order = [first] + [f for f in pair if f != first]
        host = effect == "field_dependence" and "driver_lag" in row["effects"]
        target = truth.loguniform(sizes_rng, *(HOST_SIZES if host else SIZES)) * sigma
        tried = []
        for form in order:
            if family == "damper":
                reference = {k: v for k, v in spec.items() if effect == "driver_lag"}
                p, reached, what = ctx.size(
                    effect, form, effects_rng, target, reference
                )
            else:
                p, reached, what = ctx.size(effect, form, effects_rng, target)
            tried.append((form, reached, p, what))
            # A form that reaches its size, or at least the exam's smallest size,
            # is kept; otherwise the effect's other form is tried.
            if reached >= truth.REACHED * min(target, SIZES[0] * sigma):
                break
        form, reached, p, what = max(tried, key=lambda f: f[1])
        spec[effect] = (form, p)
        forms[effect] = form
        sizes[effect] = reached / sigma
        note = (
            ""
            if reached >= truth.REACHED * target
            else f" (asked {target / sigma:.3g})"
        )
        if form != first:
            note += f" ({first} reached less)"
        words.append(f"{effect} [{form}]: {what}; {reached / sigma:.3g} sigma{note}")
    return spec, forms, sizes, words


def generate(family: str, row: dict, seed: int):
    """(recording, metadata) of one record."""
    start = time.perf_counter()
    index = row["index"]
    base_rng = _rng(seed, family, index, "base")
    input_rng = _rng(seed, family, index, "input")
    noise_rng = _rng(seed, family, index, "noise")
    command = None
    if family == "piezo":
        model = jh.synthetic.base_truth(_key(seed, family, index))
        base = {k: float(v) for k, v in model.parameters().items()}
        t, u, f, what_input = piezo_drive(input_rng, row["protocol"], row["effects"])
        ctx = truth.Piezo(t, u, base, f)
        sigma = truth.loguniform(noise_rng, 5e-4, 2e-3) * float(np.ptp(ctx.y_base))
        phi = (0.85, 0.97)
    elif family == "structural":
        model = jh.synthetic.structural_base_truth(_key(seed, family, index))
        base = {k: float(v) for k, v in model.parameters().items()}
        x_y = (1 / (base["beta"] + base["gamma"])) ** (1 / base["n"])
        u, what_input = structural_protocol(input_rng, row["protocol"], x_y)
        t = np.arange(u.size, dtype=float)
        ctx = truth.Structural(u, base)
        sigma = truth.loguniform(noise_rng, 0.006, 0.015) * float(
            np.max(np.abs(ctx.y_base))
        )
        phi = (0.5, 0.9)
    else:
        t, u, command, what_input = damper_drive(input_rng, row["protocol"])
        base = damper_base(base_rng, u)
        ctx = truth.Damper(t, u, command, base)
        sigma = truth.loguniform(noise_rng, 0.005, 0.015) * float(
            np.max(np.abs(ctx.y_base))
        )
        phi = (0.5, 0.9)
    spec, forms, sizes, words = _size_effects(ctx, row, seed, family, sigma)
    y_true = ctx.outputs([spec])[0] if spec else ctx.y_base
    change = y_true - ctx.y_base
    e, what_noise = truth.noise(noise_rng, row["noise"], sigma, y_true.size, phi)
    seen = truth.visible(change, ctx.columns) / sigma if spec else 0.0
    if family == "piezo":
        recording = jh.Recording(
            t,
            u,
            y_true + e,
            name=row["name"],
            input_name="u",
            output_name="y",
            input_unit="V",
            output_unit="um",
        )
    elif family == "structural":
        recording = jh.Recording(
            t,
            u,
            y_true + e,
            name=row["name"],
            input_name="displacement",
            output_name="force",
            input_unit="mm",
            output_unit="kN",
            time_unit="sample",
        )
    else:
        recording = jh.Recording(
            t,
            u,
            y_true + e,
            name=row["name"],
            input_name="displacement",
            output_name="force",
            input_unit="cm",
            output_unit="N",
            more_inputs={"command": command},
            more_input_units={"command": "V"},
        )
    meta = {
        "name": row["name"],
        "family": family,
        "index": index,
        "truth": list(row["effects"]),
        "forms": forms,
        "preferred": row["preferred"],
        "protocol": row["protocol"],
        "noise": row["noise"],
        "sigma": sigma,
        "sizes": sizes,
        "raw_sigmas": truth.rms(change) / sigma,
        "visible_sigmas": seen,
        "confirmable": bool(spec) and seen >= CONFIRMABLE,
        "base": base,
        "description": [what_input, *words, f"noise {what_noise}, sigma {sigma:.4g}"],
        "generate_seconds": time.perf_counter() - start,
    }
    return recording, meta


def _inputs(family: str) -> tuple[str, str]:
    if family == "piezo":
        return "u", "y"
    if family == "structural":
        return "displacement", "force"
    return "displacement command", "force"


def save_record(folder: Path, recording, meta: dict) -> None:
    """The recording as CSV (checked to read back bit-identical) and its truth."""
    path = folder / f"{meta['name']}.csv"
    recording.save(path, overwrite=True)
    inputs, output = _inputs(meta["family"])
    back = jh.Recording.load(path, input=inputs.split(), output=output)
    pairs = [(recording.t, back.t), (recording.u, back.u), (recording.y, back.y)]
    if meta["family"] == "damper":
        pairs.append((recording.more_input("command"), back.more_input("command")))
    for a, b in pairs:
        if not np.array_equal(np.asarray(a), np.asarray(b)):
            raise RuntimeError(f"{path} does not read back bit-identical")
    (folder / f"{meta['name']}.json").write_text(json.dumps(meta, indent=1))


def write_manifest(out: Path, metas: list[dict], seed: int) -> Path:
    manifest = out / "manifest.csv"
    header = ["recording", "command", "name", "model", "input", "output", "seed"]
    header += ["family", "truth", "forms", "sigma", "noise", "protocol", "sizes"]
    header += ["visible", "confirmable"]
    with open(manifest, "w", newline="") as file:
        writer = csv.writer(file)
        writer.writerow(header)
        for m in metas:
            inp, outp = _inputs(m["family"])
            writer.writerow(
                [
                    f"recordings/{m['name']}.csv",
                    "diagnose",
                    m["name"],
                    MODEL[m["family"]],
                    inp,
                    outp,
                    seed,
                    m["family"],
                    "+".join(m["truth"]),
                    " ".join(f"{k}:{v}" for k, v in m["forms"].items()),
                    repr(m["sigma"]),
                    m["noise"],
                    m["protocol"],
                    " ".join(f"{k}:{v:.3g}" for k, v in m["sizes"].items()),
                    f"{m['visible_sigmas']:.3g}",
                    int(m["confirmable"]),
                ]
            )
    return manifest


def records(args, families, folder: Path | None) -> list[dict]:
    """Every selected record's metadata, generated (and saved into `folder`) or
    read back from an earlier run's `folder`."""
    metas = []
    for family in families:
        plan = _plan(family)
        if args.limit is not None:
            plan = plan[: args.limit]
        for row in plan:
            known = folder / f"{row['name']}.json" if folder else None
            if (
                known is not None
                and known.is_file()
                and known.with_suffix(".csv").is_file()
            ):
                meta = json.loads(known.read_text())
                if (meta.get("seed"), meta.get("generator")) == (args.seed, GENERATOR):
                    metas.append(meta)
                    continue
            recording, meta = generate(family, row, args.seed)
            meta["seed"] = args.seed
            meta["generator"] = GENERATOR
            if folder is not None:
                save_record(folder, recording, meta)
            metas.append(meta)
            print(_dry_line(meta), flush=True)
    return metas


def _dry_line(m: dict) -> str:
    sizes = ", ".join(f"{k} {v:.1f} {m['forms'][k]}" for k, v in m["sizes"].items())
    flag = "" if m["confirmable"] or not m["truth"] else " NOT CONFIRMABLE"
    return (
        f"{m['name']:<44} {m['protocol']:<10} {m['noise']:<8} sizes(sigma): "
        f"{sizes or '-'}; visible {m['visible_sigmas']:.1f}, raw {m['raw_sigmas']:.1f}"
        f"{flag} ({m['generate_seconds']:.1f} s)"
    )


# ----------------------------------------------------------------------- scoring


@functools.cache
def _folder_names(out: Path) -> dict[str, str]:
    return {
        Path(record.recording).stem: record.name
        for record in read_manifest(out / "manifest.csv").records
    }


def record_folder(out: Path, name: str) -> Path:
    """The batch's folder of the record `name` (the batch makes a record's folder
    name file-safe, `a+b` -> `a_b`: read it from the manifest)."""
    return out / "records" / _folder_names(out).get(name, name)


def read_result(out: Path, name: str) -> dict | None:
    """The record's diagnosis JSON, with the batch's wall seconds under
    "batch_seconds" (None when the batch did not finish the record)."""
    folder = record_folder(out, name)
    path = folder / "result.json"
    if not path.is_file():
        return None
    result = json.loads(path.read_text())
    outcome = folder / "outcome.json"
    if outcome.is_file():
        result["batch_seconds"] = json.loads(outcome.read_text()).get("seconds")
    return result


def score_record(m: dict, result: dict | None) -> dict:
    truth_ = set(m["truth"])
    row = {
        "name": m["name"],
        "family": m["family"],
        "truth": sorted(truth_),
        "forms": m["forms"],
        "protocol": m["protocol"],
        "noise": m["noise"],
        "sizes": m["sizes"],
        "visible_sigmas": m["visible_sigmas"],
        "confirmable": m["confirmable"],
        "done": result is not None,
    }
    if result is None:
        return row | {"named": [], "exact": False, "false_claims": [], "strict": []}
    named = [f["effect"] for f in result["findings"]]
    undecided = set(result.get("undecided", []))
    excess = sorted(set(named) - truth_)
    # An ambiguity that leaves a truth effect open excuses the claim.
    false = [] if truth_ & undecided else excess
    final = result["final"]["rmse"]
    return row | {
        "named": named,
        "undecided": sorted(undecided),
        "ambiguities": result.get("ambiguities", []),
        "exact": set(named) == truth_,
        "false_claims": false,
        "strict": excess,
        "final_over_sigma": final / m["sigma"] if final is not None else math.nan,
        "baseline_over_sigma": result["baseline"]["rmse"] / m["sigma"],
        "seconds": result.get("timing", {}).get("total_s"),
        "batch_seconds": result.get("batch_seconds"),
    }


def _share(values) -> float:
    values = list(values)
    return sum(values) / len(values) if values else math.nan


def summarise(rows: list[dict]) -> dict:
    effect_rows = [r for r in rows if r["truth"]]
    clean = [r for r in rows if not r["truth"]]
    # A record the batch did not diagnose fails every bar it counts in.
    confirm = [r for r in effect_rows if r["confirmable"]]
    false = sum(len(r["false_claims"]) for r in rows)
    seconds = [r["seconds"] for r in rows if r.get("seconds") is not None]
    effects = sorted({e for r in rows for e in r["truth"]})
    named = sorted({e for r in rows for e in r["named"]} - set(effects))
    columns = [*effects, *named, "none"]
    counts: Counter = Counter()
    for r in rows:
        for t in r["truth"] or ["none"]:
            for g in r["named"] or ["none"]:
                counts[t, g] += 1
    summary = {
        "records": len(rows),
        "diagnosed": sum(r["done"] for r in rows),
        "effect_records": len(effect_rows),
        "exact_effect_records": _share(r["exact"] for r in effect_rows),
        "exact_all_records": _share(r["exact"] for r in rows),
        "false_claims": false,
        "false_claims_per_40": 40 * false / len(rows) if rows else math.nan,
        "records_with_false_claims": sum(bool(r["false_claims"]) for r in rows),
        "strict_false_claims": sum(len(r["strict"]) for r in rows),
        "clean_records": len(clean),
        "clean_silent": sum(r["done"] and not r["named"] for r in clean),
        "confirmable_records": len(confirm),
        "final_within_bar": _share(
            r.get("final_over_sigma", math.nan) <= FINAL_BAR for r in confirm
        ),
        "median_final_over_sigma": statistics.median(
            [r["final_over_sigma"] for r in rows if r["done"]] or [math.nan]
        ),
        "median_seconds": statistics.median(seconds) if seconds else math.nan,
        "confusion": {
            "rows": [*effects, "none"],
            "columns": columns,
            "counts": [[counts[t, c] for c in columns] for t in [*effects, "none"]],
        },
    }
    summary["bars"] = {
        "exact >= 85 %": summary["exact_effect_records"] >= BARS["exact"],
        "false claims <= 1 per 40": summary["false_claims_per_40"]
        <= BARS["false_per_40"],
        "every clean record silent": summary["clean_silent"] == len(clean),
        "final <= 1.3 sigma on >= 85 %": summary["final_within_bar"] >= BARS["final"],
    }
    return summary


def print_family(family: str, rows: list[dict], s: dict) -> None:
    print()
    print(f"== {family}: {s['records']} records ({s['diagnosed']} diagnosed)")
    for r in rows:
        if not r["done"]:
            print(f"  {r['name']:<44} not diagnosed")
            continue
        mark = "ok  " if r["exact"] else ("FALSE" if r["false_claims"] else "miss")
        open_ = f" undecided {'+'.join(r['undecided'])}" if r["undecided"] else ""
        print(
            f"  {mark} {r['name']:<44} named {'+'.join(r['named']) or '-':<28} "
            f"final {r['final_over_sigma']:.2f} sigma (base {r['baseline_over_sigma']:.2f})"
            f"{open_} {r['seconds'] or 0:.0f} s"
        )
    print(
        f"exact sets (effect records): {s['exact_effect_records']:.1%} of "
        f"{s['effect_records']} (all records {s['exact_all_records']:.1%})"
    )
    print(
        f"false claims: {s['false_claims']} ({s['false_claims_per_40']:.2f} per 40 "
        f"records; strict, ambiguities aside: {s['strict_false_claims']})"
    )
    print(f"clean records silent: {s['clean_silent']}/{s['clean_records']}")
    print(
        f"final <= {FINAL_BAR} sigma on confirmable effect records: "
        f"{s['final_within_bar']:.1%} of {s['confirmable_records']} (median final "
        f"{s['median_final_over_sigma']:.2f} sigma, all records)"
    )
    print(f"median seconds per record: {s['median_seconds']:.1f}")
    for bar, met in s["bars"].items():
        print(f"  bar {bar}: {'met' if met else 'NOT MET'}")
    c = s["confusion"]
    width = 8
    first = max(len(r) for r in c["rows"]) + 2
    print("confusion (rows: true effect, columns: named effect)")
    print(" " * first + " ".join(f"{col[:width]:>{width}}" for col in c["columns"]))
    for name, counts in zip(c["rows"], c["counts"]):
        print(f"{name:<{first}}" + " ".join(f"{n:>{width}d}" for n in counts))


def score(out: Path, metas: list[dict], families, json_path) -> dict:
    report: dict = {
        "machine": common.machine_info("dask", "distributed"),
        "families": {},
    }
    for family in families:
        ms = [m for m in metas if m["family"] == family]
        if not ms:
            continue
        rows = [score_record(m, read_result(out, m["name"])) for m in ms]
        summary = summarise(rows)
        print_family(family, rows, summary)
        report["families"][family] = {"summary": summary, "records": rows}
    if json_path:
        common.write_json(report, json_path)
    return report


# -------------------------------------------------------------------------- main


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--family", choices=[*FAMILIES, "all"], default="all")
    parser.add_argument(
        "--limit", type=int, default=None, help="first N records per family"
    )
    parser.add_argument(
        "--dry-run", action="store_true", help="generate and print only"
    )
    parser.add_argument(
        "--out", default=None, help="keep the batch folder (a rerun resumes)"
    )
    parser.add_argument("--score-only", metavar="DIR", default=None)
    parser.add_argument(
        "--ran-only",
        action="store_true",
        help="with --score-only: score the records the batch has run (done or "
        "failed) and say how many are left; a partial exam scores nothing else",
    )
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--seed", type=int, default=0)
    common.add_json(parser)
    args = parser.parse_args(argv)
    families = FAMILIES if args.family == "all" else (args.family,)
    if args.score_only:
        out = Path(args.score_only)
        metas = [
            json.loads(p.read_text())
            for p in sorted((out / "recordings").glob("*.json"))
        ]
        metas = [m for m in metas if m["family"] in families]
        if args.limit is not None:
            metas = [m for m in metas if m["index"] < args.limit]
        if args.ran_only:
            ran = [m for m in metas if record_folder(out, m["name"]).is_dir()]
            print(f"scoring the {len(ran)} of {len(metas)} records the batch ran")
            metas = ran
        score(out, metas, families, args.json)
        return 0
    if args.dry_run:
        metas = records(args, families, None)
        for family in families:
            ms = [m for m in metas if m["family"] == family]
            effect = [m for m in ms if m["truth"]]
            if effect:
                sizes = [v for m in effect for v in m["sizes"].values()]
                print(
                    f"{family}: {len(ms)} records, {len(effect)} with effects; sizes "
                    f"{min(sizes):.1f}-{max(sizes):.1f} sigma, visible "
                    f"{min(m['visible_sigmas'] for m in effect):.1f}-"
                    f"{max(m['visible_sigmas'] for m in effect):.1f}, raw "
                    f"{min(m['raw_sigmas'] for m in effect):.1f}-"
                    f"{max(m['raw_sigmas'] for m in effect):.1f}; "
                    f"{sum(not m['confirmable'] for m in effect)} not confirmable"
                )
        if args.json:
            common.write_json({"records": metas}, args.json)
        return 0
    with tempfile.TemporaryDirectory(prefix="jaxhyst-exam-") as tmp:
        out = Path(args.out) if args.out else Path(tmp)
        (out / "recordings").mkdir(parents=True, exist_ok=True)
        metas = records(args, families, out / "recordings")
        manifest = write_manifest(out, metas, args.seed)
        print(f"{len(metas)} records in {manifest}", flush=True)
        result = jh.batch(
            manifest, out, cluster=jh.LocalWorkers(args.workers, 1), progress=True
        )
        print(f"batch: {result.failed} failed", flush=True)
        score(out, metas, families, args.json)
    return 0


if __name__ == "__main__":
    sys.exit(main())
