"""Hysteresis compensation on a plant the models never saw: does naming the
missing physics make the feedforward track better?

The plant is the concealed-truth stage of `jh.synthetic.concealed_recording` (a paper-like
piezo stage with the named effects hidden in it; its generator is independent of
the models being inverted). From its training record (the rich excitation, 45 s at
1 kHz, noise) three models are identified: the plain piezo fit (`identify`), the
paper's corrected model (piezo, then phi/eps, then all eight) and the diagnosed
model (`diagnose`'s final model). Each is inverted with `jh.compensate` (the
per-sample inversion where the model allows it, else the optimised drive) on
references the fits never saw, in the plant's output range:

- `u1_0.1Hz`: the paper's u1 shape (raised cosine) at 0.1 Hz, 10 s;
- `u2_1Hz`: the same at 1 Hz, 5 s;
- `multitone`: three tones (0.2, 0.7, 1.9 Hz), 10 s;
- `staircase`: steps with holds (ramped over 0.2 s), 10 s;

all at 1 kHz, 10 % to 90 % of the plant's stroke under the training drive range. The
drive goes through the TRUE plant (`simulate(case.truth, drive)`); the tracking error
is the plant's output minus the reference; its spectrum (`jh.error_spectrum`, octave
bands) says where in frequency it lies. "none" is the uncompensated drive: the
reference scaled by the straight line fitted to the training record (u against y).

    python benchmarks/compensation.py [--effects clean asymmetry creep ...] [--json OUT]
"""

import argparse
import time

import _common as common
import jax
import numpy as np

import jaxhyst as jh


jax.config.update("jax_enable_x64", True)

RATE = 1000.0


def references(y_lo: float, y_hi: float) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """The unseen references, scaled into 10-90 % of [y_lo, y_hi]."""

    def scaled(shape):
        shape = (shape - shape.min()) / np.ptp(shape)
        return y_lo + (y_hi - y_lo) * (0.1 + 0.8 * shape)

    t10 = np.arange(0.0, 10.0, 1 / RATE)
    t5 = np.arange(0.0, 5.0, 1 / RATE)
    levels = np.array([0.2, 0.6, 0.35, 0.9, 0.1, 0.7, 0.5])
    step = np.minimum(np.floor(t10 / (10 / len(levels))).astype(int), len(levels) - 1)
    stairs = levels[step]
    ramp = int(0.2 * RATE)
    kernel = np.ones(ramp) / ramp
    stairs = np.convolve(np.concatenate([np.full(ramp, stairs[0]), stairs]), kernel)[
        ramp : ramp + t10.size
    ]
    tones = sum(
        a * np.sin(2 * np.pi * f * t10 + p)
        for a, f, p in ((1.0, 0.2, 0.0), (0.5, 0.7, 1.0), (0.3, 1.9, 2.0))
    )
    return {
        "u1_0.1Hz": (t10, scaled(1 - np.cos(2 * np.pi * 0.1 * t10))),
        "u2_1Hz": (t5, scaled(1 - np.cos(2 * np.pi * 1.0 * t5))),
        "multitone": (t10, scaled(np.asarray(tones))),
        "staircase": (t10, scaled(stairs)),
    }


def corrected_fit(recording, key):
    return jh.identification.identify_corrected(recording, key=key)[0].model


def tracking(t, y, reference, stroke):
    """RMS and maximum tracking error in % of the stroke, and where the error lies
    in frequency (`jh.error_spectrum`: octave bands; `dominant`: the band with the
    largest share of the mean square)."""
    error = y - reference
    spectrum = jh.error_spectrum(t, error, stroke=stroke)
    low, high, share = spectrum.dominant()
    return {
        "rms_percent": float(100 * np.sqrt(np.mean(error**2)) / stroke),
        "max_percent": float(100 * np.max(np.abs(error)) / stroke),
        "dominant": {"low_hz": low, "high_hz": high, "share": share},
        "spectrum": spectrum.to_json(),
    }


def band(cell):
    """'0.4-0.8 Hz 84 %': the cell's dominant error band and its share."""
    d = cell["dominant"]
    where = "mean" if d["high_hz"] == 0 else f"{d['low_hz']:.2g}-{d['high_hz']:.2g} Hz"
    return f"{where} {100 * d['share']:.0f}%"


def run_case(effects, seed, inverted=("plain", "corrected", "diagnosed")):
    key = jax.random.key(seed)
    case = jh.synthetic.concealed_recording(
        tuple(effects), key=jax.random.fold_in(key, 0), noise="white"
    )
    recording = case.recording
    lo, hi = float(np.min(recording.u)), float(np.max(recording.u))
    start = time.perf_counter()
    plain = jh.identify(
        jh.PiezoBoucWen(1.0, 1.0, 1.0, 1.0, 1.0, 1.5),
        recording,
        key=jax.random.fold_in(key, 1),
        analyse=False,
        throw=False,
    ).model
    corrected = (
        corrected_fit(recording, jax.random.fold_in(key, 2))
        if "corrected" in inverted
        else None
    )
    diagnosis = jh.diagnose(recording, key=jax.random.fold_in(key, 3))
    fit_seconds = time.perf_counter() - start
    models = {
        "plain": plain,
        "corrected": corrected,
        "diagnosed": diagnosis.final_model,
    }
    # The plant's stroke under the training drive range (a slow full cycle).
    t_cycle = np.arange(0.0, 20.0, 1 / RATE)
    u_cycle = lo + (hi - lo) * 0.5 * (1 - np.cos(2 * np.pi * 0.1 * t_cycle))
    plant_cycle = np.asarray(
        jh.simulate(case.truth, jh.InputPath(0.0, 1 / RATE, u_cycle), case.solver)
    )
    y_lo, y_hi = float(plant_cycle.min()), float(plant_cycle.max())
    stroke = y_hi - y_lo
    slope, intercept = np.polyfit(recording.y, recording.u, 1)
    rows = {}
    for name, (t, reference) in references(y_lo, y_hi).items():
        row = {}
        none = np.clip(intercept + slope * reference, lo, hi)
        y = jh.simulate(case.truth, jh.InputPath(0.0, 1 / RATE, none), case.solver)
        row["none"] = tracking(t, np.asarray(y), reference, stroke)
        for label, model in models.items():
            if label not in inverted:
                continue
            t0 = time.perf_counter()
            result = jh.compensate(model, t, reference, limits=(lo, hi), throw=False)
            seconds = time.perf_counter() - t0
            y = jh.simulate(
                case.truth, jh.InputPath(0.0, 1 / RATE, result.drive), case.solver
            )
            row[label] = {
                **tracking(t, np.asarray(y), reference, stroke),
                "method": result.method,
                "samples_at_limit": result.tracking()["samples_at_limit"],
                "seconds": seconds,
            }
        rows[name] = row
    return {
        "effects": list(effects),
        "diagnosed_effects": [f.effect for f in diagnosis.findings],
        "stroke": stroke,
        "fit_seconds": fit_seconds,
        "references": rows,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument(
        "--effects",
        nargs="+",
        default=["clean", "asymmetry", "input_bias", "creep", "dynamics"],
        help="cases: 'clean' or effect names joined by '+'",
    )
    parser.add_argument("--seed", type=int, default=0)
    common.add_subset(
        parser,
        "--models",
        ["plain", "corrected", "diagnosed"],
        help="the models to invert (the corrected model's optimised drive takes "
        "minutes per reference where its asymmetry term makes the fit nonsmooth)",
    )
    common.add_json(parser)
    args = parser.parse_args()
    results = []
    for label in args.effects:
        effects = () if label == "clean" else tuple(label.split("+"))
        result = run_case(effects, args.seed, tuple(args.models))
        results.append(result)
        print(
            f"{label}: diagnosed {'+'.join(result['diagnosed_effects']) or 'none'}; "
            f"fits {result['fit_seconds']:.0f} s",
            flush=True,
        )
        for name, row in result["references"].items():
            cells = "  ".join(
                f"{k} {v['rms_percent']:.3f}/{v['max_percent']:.2f} ({band(v)})"
                + (f" [{v['seconds']:.2f} s]" if "seconds" in v else "")
                for k, v in row.items()
            )
            print(
                f"  {name:<10} RMS/max % of stroke (dominant error band) "
                f"[compensate s]: {cells}",
                flush=True,
            )
    common.write_results(args.json, cases=results)


if __name__ == "__main__":
    main()
