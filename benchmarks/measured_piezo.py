"""A measured piezoelectric actuator (Chandra et al. 2023, GitHub
chandratue/SmartHysteresis): voltage [V] -> displacement [um], 5 kHz, 10 s.

The voltage is 0 until t = 3.257 s, then steps to about -87 V and continues as a
150 V, 1 Hz sine (about 6.7 cycles). This script

1. describes the record: the output at 0 V before the switch-on (an offset), the
   noise there, and the transient after the step (ringing frequency and decay);
2. fits the quasi-static piezo model (`jh.PiezoBoucWen`, eq. 7-8) and the corrected
   model (`jh.CorrectedPiezoBoucWen`, eq. 16-17: input time shift phi and
   asymmetry eps) with `jh.identify` to the periodic part: the models are simulated
   from the last 0 V sample before the step (so the hysteresis state follows the
   input from rest), and the loss counts only t >= `--fit-start` (4 s), after the
   step's ringing. The corrected model is polished from the better of its own swarm
   and the plain fit (it nests the plain model at phi = eps = 0);
3. runs `jh.diagnose` on the whole record and on the periodic part: from the first
   time after `--fit-start` where the fitted model's hysteretic state h crosses zero
   (the diagnosis simulates from h = 0; starting anywhere else on the loop adds a
   start-up error that is no physics), at
   `--diagnosis-rate` (default 1 kHz: the output is decimated with a zero-phase FIR
   filter, the input, a sine and one step, is subsampled). At 1 kHz the ringing
   (about 1 kHz) is above the Nyquist frequency and cannot be seen; pass
   `--diagnosis-rate 5000` to keep it (slower).

A single 1 Hz excitation cannot separate every effect: a time shift of the drive
(input_bias), rate dependence and a fast stage (dynamics) all widen the loop in
proportion to the rate at one frequency; several rates (and holds) are needed to
tell them apart.

    python benchmarks/measured_piezo.py
    python benchmarks/measured_piezo.py --json piezo.json --out jaxhyst-out/piezo
"""

import argparse
import sys
import time
from pathlib import Path

import jax


jax.config.update("jax_enable_x64", True)

import _common as common  # noqa: E402
import numpy as np  # noqa: E402
from scipy import signal  # noqa: E402

import jaxhyst as jh  # noqa: E402


def parse_args(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    common.add_record_options(
        parser, "piezo_actuator_smarthysteresis/", "jaxhyst-out/measured_piezo"
    )
    parser.add_argument(
        "--fit-start",
        type=float,
        default=4.0,
        help="the loss counts samples from this time on [s] (default 4)",
    )
    parser.add_argument(
        "--diagnosis-rate",
        type=float,
        default=1000.0,
        help="sample rate for jh.diagnose [Hz], a divisor of 5000 (default 1000)",
    )
    parser.add_argument(
        "--skip-diagnosis", action="store_true", help="only describe and fit"
    )
    return parser.parse_args(argv)


def load(data_dir):
    try:
        return jh.datasets.load_piezo_actuator(data_dir=data_dir)
    except FileNotFoundError as error:
        raise SystemExit(
            f"measured_piezo: cannot load the piezo record.\n{error}"
        ) from None


def metrics(y, yhat) -> dict:
    return {k: float(v) for k, v in jh.error_metrics(y, yhat).items()}


# --------------------------------------------------------------------------- steps


def describe(record: jh.Recording) -> dict:
    """Offset at 0 V, noise, and the ringing after the switch-on step."""
    t, u, y = record.t, record.u, record.y
    step = int(np.argmax(np.abs(np.diff(u)))) + 1
    before = y[:step]
    # Noise: the 0 V stretch minus a slow trend (1 s moving average).
    width = int(record.sample_rate)
    trend = np.convolve(before, np.ones(width) / width, mode="same")
    inner = slice(width, before.size - width)
    noise = float(np.std((before - trend)[inner]))
    # Ringing: the first 50 ms after the step, minus a cubic trend.
    span = int(0.05 * record.sample_rate)
    window = y[step : step + span]
    k = np.arange(span)
    ringing = window - np.polyval(np.polyfit(k, window, 3), k)
    spectrum = np.abs(np.fft.rfft(ringing * np.hanning(span)))
    freqs = np.fft.rfftfreq(span, record.dt)
    peak = float(freqs[1:][np.argmax(spectrum[1:])])
    envelope = np.abs(signal.hilbert(ringing))
    settled = np.flatnonzero(envelope > 3 * noise)
    settle_time = float(settled[-1] / record.sample_rate) if settled.size else 0.0
    return {
        "step_index": step,
        "step_time": float(t[step]),
        "step_to": float(u[step]),
        "offset_at_0V_mean": float(np.mean(before)),
        "offset_at_0V_std": float(np.std(before)),
        "noise_sigma": noise,
        "ringing_frequency_hz": peak,
        "ringing_peak_amplitude": float(np.max(np.abs(ringing[:10]))),
        "ringing_settles_within_s": settle_time,
    }


def fit_models(record: jh.Recording, info: dict, fit_start: float, seed: int) -> dict:
    """PiezoBoucWen and CorrectedPiezoBoucWen, simulated from the last 0 V sample,
    scored from `fit_start` on."""
    step = info["step_index"]
    segment = record.segment(record.t[step - 1], None)
    weights = (segment.t >= fit_start - 1e-9).astype(float)
    scored = weights > 0
    key = jax.random.key(seed)
    out = {"segment": segment, "scored": scored}
    start = time.perf_counter()
    plain = jh.identify(
        jh.PiezoBoucWen(1.0, 1.0, 1.0, 1.0, 1.0, 1.5),
        segment,
        key=key,
        weights=weights,
    )
    out["piezo_seconds"] = time.perf_counter() - start
    start = time.perf_counter()
    corrected = jh.identify(
        jh.CorrectedPiezoBoucWen(1.0, 1.0, 1.0, 1.0, 1.0, 1.5),
        segment,
        key=jax.random.fold_in(key, 1),
        weights=weights,
        start=jh.CorrectedPiezoBoucWen.from_piezo(plain.model),
    )
    out["corrected_seconds"] = time.perf_counter() - start
    # Where the fitted hysteretic state crosses zero after `fit_start`: a record
    # that starts there is consistent with the models' initial state h = 0.
    _, states = jh.simulate(
        plain.model, segment.input_path(), jh.RK4(), return_state=True
    )
    h = np.asarray(states)[:, 0]
    after = np.flatnonzero(scored[1:] & (np.sign(h[1:]) != np.sign(h[:-1])))
    out["periodic_start"] = float(segment.t[after[0] + 1]) if after.size else fit_start
    for name, fit in (("piezo", plain), ("corrected", corrected)):
        predicted = np.asarray(fit.predicted)
        residual = segment.y - predicted
        out[name] = fit
        out[f"{name}_metrics"] = metrics(segment.y[scored], predicted[scored])
        out[f"{name}_mean_residual"] = float(np.mean(residual[scored]))
        out[f"{name}_parameters"] = {
            k: float(v) for k, v in fit.model.parameters().items()
        }
    return out


def decimated(record: jh.Recording, rate: float) -> jh.Recording:
    factor = round(record.sample_rate / rate)
    if factor < 1 or abs(record.sample_rate / factor - rate) > 1e-6 * rate:
        raise SystemExit(
            f"measured_piezo: --diagnosis-rate {rate} must divide "
            f"{record.sample_rate:g} Hz."
        )
    if factor == 1:
        return record
    y = signal.decimate(record.y, factor, ftype="fir", zero_phase=True)
    return jh.Recording(
        record.t[::factor],
        record.u[::factor],
        y,
        name=f"{record.name}_{rate:g}Hz",
        input_name=record.input_name,
        output_name=record.output_name,
        input_unit=record.input_unit,
        output_unit=record.output_unit,
    )


# ------------------------------------------------------------------------- figures


def figures(out: Path, record, info, fits, diagnoses) -> list[str]:
    writer = common.FigureWriter(out)
    new, save = writer.new, writer.save
    segment, scored = fits["segment"], fits["scored"]
    piezo = np.asarray(fits["piezo"].predicted)
    corrected = np.asarray(fits["corrected"].predicted)
    u, y = segment.u[scored], segment.y[scored]
    slope, intercept = np.polyfit(u, y, 1)
    figure, (top, bottom) = new(2, 8.0)
    top.plot(u, y, linewidth=0.8, label="measured")
    top.plot(u, piezo[scored], "--", linewidth=0.8, label="piezo (eq. 7-8)")
    top.plot(u, corrected[scored], ":", linewidth=0.8, label="corrected (eq. 16-17)")
    top.set_ylabel("displacement [um]")
    top.set_title("Measured piezo actuator, periodic part (t >= fit start)")
    top.legend(loc="upper left", fontsize="small")
    line = slope * u + intercept
    bottom.plot(u, y - line, linewidth=0.8, label="measured")
    bottom.plot(u, piezo[scored] - line, "--", linewidth=0.8, label="piezo")
    bottom.plot(u, corrected[scored] - line, ":", linewidth=0.8, label="corrected")
    bottom.set_xlabel("voltage [V]")
    bottom.set_ylabel("minus the straight line [um]")
    bottom.set_title(f"loop opening (minus {slope:.4g} u + {intercept:.3g})")
    for axis in (top, bottom):
        axis.grid(alpha=0.3)
    save(figure, "loops.png")

    figure, (top, bottom) = new(2, 6.5)
    t = segment.t
    top.plot(t, segment.y - piezo, linewidth=0.4, label="measured - piezo")
    top.plot(t, segment.y - corrected, linewidth=0.4, label="measured - corrected")
    top.axvline(t[scored][0], color="0.4", linestyle="--", linewidth=0.8)
    top.set_ylabel("residual [um]")
    top.set_title("Residuals from the switch-on (the loss starts at the dashed line)")
    top.legend(loc="upper right", fontsize="small")
    step = info["step_index"]
    near = slice(max(0, step - 25), step + 300)
    top_t = record.t[near]
    bottom.plot(top_t, record.y[near], label="measured")
    base = jh.simulate(
        fits["piezo"].model,
        jh.InputPath(record.t[near][0], record.dt, record.u[near]),
    )
    bottom.plot(top_t, np.asarray(base), "--", label="piezo (quasi-static)")
    bottom.set_xlabel("time [s]")
    bottom.set_ylabel("displacement [um]")
    bottom.set_title(
        f"the switch-on step: ringing at about {info['ringing_frequency_hz']:.0f} Hz"
    )
    bottom.legend(loc="upper right", fontsize="small")
    for axis in (top, bottom):
        axis.grid(alpha=0.3)
    save(figure, "residuals_and_step.png")

    for label, diag in diagnoses.items():
        rec = diag["recording"]
        result = diag["result"]
        figure, (axis,) = new(1, 4.0)
        axis.plot(
            rec.t,
            rec.y - np.asarray(result.base_predicted),
            linewidth=0.5,
            label=f"piezo: RMSE {diag['baseline']['rmse']:.3g} um",
        )
        name = "+".join(["piezo", *diag["effects"]])
        axis.plot(
            rec.t,
            rec.y - np.asarray(result.final_predicted),
            linewidth=0.5,
            label=f"{name}: RMSE {diag['final']['rmse']:.3g} um",
        )
        axis.set_xlabel("time [s]")
        axis.set_ylabel("residual [um]")
        axis.set_title(f"jh.diagnose, {label} ({rec.sample_rate:g} Hz)")
        axis.legend(loc="upper right", fontsize="small")
        axis.grid(alpha=0.3)
        save(figure, f"diagnosis_{label.replace(' ', '_')}.png")
    return writer.written


# ---------------------------------------------------------------------------- main


def _identifiability(fit) -> dict | None:
    """The identifiability summary without the standard errors: jaxhyst 0.1.0's
    `identifiability` scales them by theta^2 (it multiplies the relative-change
    Jacobian by theta instead of dividing), so they are not reported here."""
    if fit.identifiability is None:
        return None
    summary = fit.identifiability.to_dict()
    summary.pop("standard_errors", None)
    return summary


def _print_diagnosis(label: str, diag: dict) -> None:
    print(
        f"diagnosis, {label} ({diag['samples']} samples at {diag['rate_hz']:g} Hz, "
        f"{diag['seconds']:.0f} s): adopted {', '.join(diag['effects']) or 'nothing'}; "
        f"RMSE {diag['baseline']['rmse']:.3g} -> {diag['final']['rmse']:.3g} um"
    )
    for finding in diag["findings"]:
        print(f"  {finding['effect']}: {finding['evidence']}")
        print(f"    parameters: {finding['parameters']}")
    for entry in diag["screened"]:
        if not entry["significant"]:
            continue
        adopted = diag["effects"][entry["round"] - 1 : entry["round"]]
        if entry["effect"] in adopted:
            verdict = "passed held-out validation, adopted"
        elif entry["accepted"]:
            verdict = "passed held-out validation, not the best this round"
        else:
            verdict = "rejected"
            if entry.get("rejected"):
                verdict += f" ({entry['rejected']})"
        held = ""
        if entry["heldout_rmse_after"] is not None:
            held = (
                f", held-out RMSE {entry['heldout_rmse_before']:.3g} -> "
                f"{entry['heldout_rmse_after']:.3g}"
            )
        print(
            f"    round {entry['round']}: {entry['effect']} score "
            f"{entry['statistic']:.0f}/{entry['dof']} dof{held}: {verdict}"
        )
    for finding in diag["findings"]:
        print(f"  {finding['effect']}: {finding['reading']}")
        rivals = ", ".join(
            f"{r['effect']} {r['margin_sigma']:+.1f} SE" for r in finding["rivals"]
        )
        verdict = "decided" if finding["decided"] else "UNDECIDED"
        print(f"    rivals ({verdict}): {rivals or 'none'}")
        if finding.get("moved"):
            print(f"    {finding['moved']}")
    for text in diag["ambiguities"]:
        print(f"  ambiguity: {text}")
    for advice in diag["advice"]:
        print(
            f"  advice: {' vs '.join(advice['separates'])}: {advice['input']} "
            f"({advice['difference_sigma']:.1f} sigma apart there, "
            f"{advice['difference_sigma_on_this_record']:.1f} on this record)"
        )
    print(f"  what is left: {diag['remainder']['sentence']}")


def main(argv=None) -> int:
    args = parse_args(argv)
    record = load(common.open_data(args))
    info = describe(record)

    common.log("fitting the piezo and corrected models ...")
    fits = fit_models(record, info, args.fit_start, args.seed)

    diagnoses = {}
    if not args.skip_diagnosis:
        slow = decimated(record, args.diagnosis_rate)
        for label, rec in (
            ("whole record", slow),
            ("periodic part", slow.segment(fits["periodic_start"], None)),
        ):
            common.log(f"diagnosing the {label} ...")
            diagnoses[label] = common.diagnose(rec, args.seed)

    print()
    print("Measured piezo actuator (SmartHysteresis, 150 V / 1 Hz), jaxhyst")
    print(
        f"record: {record.num_samples} samples at {record.sample_rate:g} Hz; the "
        f"voltage steps 0 -> {info['step_to']:.1f} V at t = {info['step_time']:.4f} s"
    )
    print(
        f"at 0 V before the step the output reads {info['offset_at_0V_mean']:.3g} um "
        f"(std {info['offset_at_0V_std']:.3g} um): an offset that a model with "
        "y = k1*u + k2*h and h = 0 at rest does not have (a sensor zero or a "
        "remanent state)"
    )
    print(
        f"noise there (minus a 1 s moving average): {info['noise_sigma']:.3g} um; "
        f"after the step the output rings at about {info['ringing_frequency_hz']:.0f} "
        f"Hz (first peak {info['ringing_peak_amplitude']:.2g} um), above 3 sigma for "
        f"{1e3 * info['ringing_settles_within_s']:.0f} ms"
    )
    print()
    print(
        f"fits (simulated from the last 0 V sample, scored on t >= {args.fit_start:g} "
        "s, metrics in um over the scored samples):"
    )
    print(
        f"  (the periodic part given to the diagnosis starts at t = "
        f"{fits['periodic_start']:.4f} s, where the fitted h crosses zero)"
    )
    print(
        f"{'model':<34} {'RMSE':>8} {'MAD':>8} {'NRMSD %':>8} {'mean res':>9} "
        f"{'seconds':>8}"
    )
    for name, label in (
        ("piezo", "piezo (eq. 7-8)"),
        ("corrected", "corrected (eq. 16-17)"),
    ):
        m = fits[f"{name}_metrics"]
        print(
            f"{label:<34} {m['rmse']:>8.4g} {m['mad']:>8.4g} {100 * m['nrmsd']:>8.3g} "
            f"{fits[f'{name}_mean_residual']:>9.3g} {fits[f'{name}_seconds']:>8.1f}"
        )
    for name in ("piezo", "corrected"):
        print(
            f"  {name}: "
            + ", ".join(f"{k}={v:.4g}" for k, v in fits[f"{name}_parameters"].items())
        )
    print()
    for label, diag in diagnoses.items():
        _print_diagnosis(label, diag)
    if diagnoses:
        print(
            "note: one 1 Hz excitation cannot separate a time shift of the drive, rate "
            "dependence and a fast stage; they all widen the loop in proportion to the "
            "rate at one frequency."
        )

    written = []
    if not args.no_figures:
        written = figures(Path(args.out), record, info, fits, diagnoses)
        print()
        print("figures: " + ", ".join(written))
    machine = common.machine_info()
    print()
    common.print_machine(machine)

    if args.json:
        result = {
            "record": info,
            "fit_start_s": args.fit_start,
            "periodic_part_start_s": fits["periodic_start"],
            "fits": {
                name: {
                    "metrics": fits[f"{name}_metrics"],
                    "mean_residual": fits[f"{name}_mean_residual"],
                    "parameters": fits[f"{name}_parameters"],
                    "seconds": fits[f"{name}_seconds"],
                    "identifiability": _identifiability(fits[name]),
                }
                for name in ("piezo", "corrected")
            },
            "diagnosis": {
                label: common.without_objects(diag) for label, diag in diagnoses.items()
            },
            "figures": written,
            "machine": machine,
        }
        common.write_json(result, args.json)
    return 0


if __name__ == "__main__":
    sys.exit(main())
