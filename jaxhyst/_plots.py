"""Paper-style plots: hysteresis loops, time histories, absolute-error trends and
residual analyses, each drawn on matplotlib Axes that the caller may compose.

Matplotlib is an optional dependency (`pip install 'jaxhyst[plot]'`) and is imported
only when a figure is made or saved. Every `plot_*` draws on the Axes it is given
(`ax=`, or `axes=` for the plots of several stacked panels) and returns them; given
none, it makes a figure of its own, built on `matplotlib.figure.Figure` with the Agg
canvas, never through `pyplot`, so plotting changes no global matplotlib state
(backend, current figure) and works headless. Nothing here writes a file but
`save_figure`, which, like `Recording.save`, refuses to replace an existing file
unless `overwrite=True`.

Curves are passed as `{label: values}` dictionaries, drawn in order: the first solid
(e.g. the measurement), the rest dashed (e.g. models), so overlaid curves stay visible.

    figure = matplotlib.figure.Figure(figsize=(10, 4), layout="constrained")
    left, right = figure.subplots(1, 2)
    jh.report.plot_loop(u, {"measured": y, "model": yhat}, ax=left)
    jh.report.plot_error_trend(t, {"model": abs(y - yhat)}, ax=right)
    jh.report.save_figure(figure, "fit.png")
"""

import os
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from jaxtyping import ArrayLike

from ._files import Refusal, refuse_existing, refuse_folder


if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure


_INSTALL_HINT = "install the plot extra: pip install 'jaxhyst[plot]'"
_DPI = 150
_STYLES = ("-", "--", "-.", ":")


def require_matplotlib() -> None:
    """Raise ImportError (with the install hint) unless matplotlib can be imported.

    Call it before a long computation whose result is to be plotted, to fail early.
    """
    _new_figure_class()


def _new_figure_class():
    try:
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure
    except ImportError:
        raise ImportError(
            f"jaxhyst plots need matplotlib, which is not installed; {_INSTALL_HINT}"
        ) from None
    return Figure, FigureCanvasAgg


def new_figure(
    rows: int = 1, *, height: float = 4.5, sharex: bool = False
) -> "tuple[Figure, list[Axes]]":
    """A 7-inch-wide figure of `rows` stacked Axes on the Agg canvas (not through
    `pyplot`), with constrained layout: the figure every `plot_*` makes when it is
    given no Axes. Returns (figure, [Axes, ...])."""
    Figure, FigureCanvasAgg = _new_figure_class()
    figure = Figure(figsize=(7.0, height), layout="constrained")
    FigureCanvasAgg(figure)
    axes = figure.subplots(rows, 1, sharex=sharex, squeeze=False)[:, 0]
    return figure, list(axes)


def _panels(
    axes: "Sequence[Axes] | None", count: int, owner: str, what: str, **figure: Any
) -> "list[Axes]":
    """The `count` Axes to draw on: `axes` (checked), or a new figure's."""
    if axes is None:
        return new_figure(count, **figure)[1]
    panels = list(np.asarray(axes, dtype=object).ravel())
    if len(panels) != count:
        raise ValueError(
            f"{owner}: axes holds {len(panels)} Axes but this plot draws {count} "
            f"({what}); pass {count} Axes, or None for a new figure."
        )
    return panels


def _axis(ax: "Axes | None", **figure: Any) -> "Axes":
    return new_figure(**figure)[1][0] if ax is None else ax


def _figure_of(figure_or_axes: Any) -> "Figure":
    """The figure to save: `figure_or_axes` itself, or the (root) figure of an Axes
    or of the first of a sequence of Axes."""
    candidate: Any = figure_or_axes
    if not hasattr(candidate, "savefig") and not hasattr(candidate, "figure"):
        panels = np.asarray(candidate, dtype=object).ravel()
        candidate = panels[0] if panels.size else None
    for _ in range(8):  # Axes -> SubFigure -> ... -> Figure
        if candidate is None or hasattr(candidate, "savefig"):
            break
        candidate = getattr(candidate, "figure", None)
    if not hasattr(candidate, "savefig"):
        raise TypeError(
            "save_figure: pass a matplotlib Figure, an Axes or a sequence of Axes, "
            f"got {type(figure_or_axes).__name__}."
        )
    return candidate


def save_figure(
    figure_or_axes: Any,
    path: str | os.PathLike,
    *,
    overwrite: bool = False,
    close: bool = True,
) -> Path:
    """Save a figure as a PNG (150 dpi) to `path` and return the path.

    `figure_or_axes`: a matplotlib `Figure`, or an Axes or array of Axes (their
    figure is saved), e.g. what a `plot_*` returned. `path` must end in `.png` and
    its folder must exist; an existing file is replaced only with `overwrite=True`.
    `close`: release a figure `pyplot` manages once saved (a figure made here, on
    the Agg canvas, needs no closing).
    """
    owner = "save_figure"
    path = Path(path)
    figure = _figure_of(figure_or_axes)
    if path.suffix.lower() != ".png":
        raise ValueError(
            f"{owner}: {str(path)!r} is not a .png path; pass a file name ending "
            "in .png."
        )
    refuse_folder(path, owner=owner)
    refuse_existing(path, overwrite=overwrite, refusal=Refusal(owner))
    if not path.parent.is_dir():
        raise FileNotFoundError(
            f"{owner}: folder {str(path.parent)!r} does not exist; create it first."
        )
    figure.savefig(path, dpi=_DPI)
    pyplot = sys.modules.get("matplotlib.pyplot")
    if close and pyplot is not None:
        pyplot.close(figure)
    return path


def _vector(values: Any, what: str, owner: str, length: int | None = None):
    array = np.asarray(values, dtype=np.float64)
    if array.ndim != 1:
        raise ValueError(
            f"{owner}: {what} must be one-dimensional, got shape {array.shape}."
        )
    if length is not None and array.shape[0] != length:
        raise ValueError(
            f"{owner}: {what} has {array.shape[0]} samples but the x-axis has "
            f"{length}; pass curves sampled at the same points."
        )
    return array


def _curves(
    curves: Mapping[str, Any], length: int, owner: str, scale: float
) -> list[tuple[str, np.ndarray]]:
    if not isinstance(curves, Mapping) or not curves:
        raise ValueError(
            f"{owner}: curves must be a non-empty dict {{label: values}}, got "
            f"{curves!r:.60}."
        )
    return [
        (str(label), scale * _vector(values, f"curve {label!r}", owner, length))
        for label, values in curves.items()
    ]


def _draw(
    axis, x: np.ndarray, curves: list[tuple[str, np.ndarray]], legend: bool = True
) -> None:
    for index, (label, values) in enumerate(curves):
        axis.plot(
            x,
            values,
            linestyle=_STYLES[min(index, len(_STYLES) - 1)],
            linewidth=1.6 if index == 0 else 1.3,
            label=label,
        )
    axis.grid(True, alpha=0.3)
    if legend and (len(curves) > 1 or curves[0][0]):
        axis.legend(loc="best", fontsize="small")


def plot_loop(
    u: ArrayLike,
    curves: Mapping[str, ArrayLike],
    *,
    xlabel: str = "input u",
    ylabel: str = "output y",
    title: str = "",
    scale: float = 1.0,
    ax: "Axes | None" = None,
) -> "Axes":
    """Hysteresis loop(s): every curve in `curves` ({label: y}) against the input `u`,
    on `ax` (None: a new figure). Returns the Axes.

    `scale` multiplies every y before drawing (e.g. 1e6 for metres -> micrometres);
    put the matching unit in `ylabel`. Where a linear part dominates (as in piezo
    actuators) the loop is thin; `plot_loop_opening` below it shows the opening.
    """
    owner = "plot_loop"
    x = _vector(u, "u", owner)
    lines = _curves(curves, x.shape[0], owner, scale)
    axis = _axis(ax, height=5.0)
    _draw(axis, x, lines)
    axis.set_xlabel(xlabel)
    axis.set_ylabel(ylabel)
    if title:
        axis.set_title(title)
    return axis


def plot_loop_opening(
    u: ArrayLike,
    curves: Mapping[str, ArrayLike],
    *,
    xlabel: str = "input u",
    ylabel: str = "output y\nminus straight line",
    title: str | None = None,
    scale: float = 1.0,
    ax: "Axes | None" = None,
) -> "Axes":
    """The loop opening: every curve in `curves` ({label: y}) minus one straight line,
    the least-squares line through the first curve, against the input `u`, on `ax`
    (None: a new figure). Returns the Axes.

    It shows the loop opening when a linear part dominates (as in piezo actuators).
    `title` None names the line subtracted. `scale` multiplies every y first.
    """
    owner = "plot_loop_opening"
    x = _vector(u, "u", owner)
    lines = _curves(curves, x.shape[0], owner, scale)
    axis = _axis(ax, height=4.0)
    slope, intercept = np.polyfit(x, lines[0][1], 1)
    line = slope * x + intercept
    _draw(
        axis,
        x,
        [(label, values - line) for label, values in lines],
        legend=len(lines) > 1,
    )
    axis.set_xlabel(xlabel)
    axis.set_ylabel(ylabel)
    if title is None:
        title = (
            f"loop opening: minus the line {slope:.4g} u "
            f"{'-' if intercept < 0 else '+'} {abs(intercept):.3g} fitted to "
            f"{lines[0][0] or 'the first curve'}"
        )
    if title:
        axis.set_title(title, fontsize="medium")
    return axis


def plot_time_history(
    t: ArrayLike,
    u: ArrayLike,
    curves: Mapping[str, ArrayLike],
    *,
    ulabel: str = "input u",
    ylabel: str = "output y",
    tlabel: str = "time t [s]",
    title: str = "",
    scale: float = 1.0,
    axes: "Sequence[Axes] | None" = None,
) -> np.ndarray:
    """Time histories: the input `u(t)` on the first of `axes`, every curve in
    `curves` ({label: y}) on the second (None: a new figure of the two, on a shared
    time axis). `scale` multiplies every y (not u). Returns the two Axes."""
    owner = "plot_time_history"
    time = _vector(t, "t", owner)
    inputs = _vector(u, "u", owner, time.shape[0])
    lines = _curves(curves, time.shape[0], owner, scale)
    top, bottom = _panels(axes, 2, owner, "input, output", height=6.0, sharex=True)
    top.plot(time, inputs, color="0.3", linewidth=1.3)
    top.grid(True, alpha=0.3)
    top.set_ylabel(ulabel)
    if title:
        top.set_title(title)
    _draw(bottom, time, lines)
    bottom.set_ylabel(ylabel)
    bottom.set_xlabel(tlabel)
    return _array(top, bottom)


def plot_error_trend(
    t: ArrayLike,
    errors: Mapping[str, ArrayLike],
    *,
    ylabel: str = "absolute error |y - yhat|",
    tlabel: str = "time t [s]",
    title: str = "Absolute error",
    scale: float = 1.0,
    log: bool = False,
    ax: "Axes | None" = None,
) -> "Axes":
    """Absolute-error trend: every series in `errors` ({label: |y - yhat|}) against
    time, on `ax` (None: a new figure). `scale` multiplies every series;
    `log=True` uses a logarithmic y-axis. Returns the Axes."""
    owner = "plot_error_trend"
    time = _vector(t, "t", owner)
    lines = _curves(errors, time.shape[0], owner, scale)
    axis = _axis(ax)
    _draw(axis, time, lines)
    if log:
        axis.set_yscale("log")
    axis.set_xlabel(tlabel)
    axis.set_ylabel(ylabel)
    if title:
        axis.set_title(title)
    return axis


def _array(*axes: Any) -> np.ndarray:
    """Axes as a one-dimensional object array, as `Figure.subplots` returns them."""
    array = np.empty(len(axes), dtype=object)
    array[:] = axes
    return array


def _binned_mean(
    x: np.ndarray, y: np.ndarray, bins: int
) -> tuple[np.ndarray, np.ndarray]:
    """Mean of `y` in `bins` equal-width bins of `x` (empty bins dropped): the
    systematic part of a noisy residual, which the raw points hide."""
    if x.size == 0:
        return x, y
    edges = np.linspace(np.min(x), np.max(x), bins + 1)
    index = np.clip(np.searchsorted(edges, x, side="right") - 1, 0, bins - 1)
    counts = np.bincount(index, minlength=bins)
    sums = np.bincount(index, weights=y, minlength=bins)
    keep = counts >= 3
    centres = 0.5 * (edges[:-1] + edges[1:])
    return centres[keep], sums[keep] / counts[keep]


def _robust_limit(series: list[tuple[str, np.ndarray]]) -> float:
    """A symmetric y-limit that holds 99.5 % of every series (a few outliers may
    be clipped), so that the systematic part is not squashed by rare spikes."""
    limit = max(float(np.quantile(np.abs(values), 0.995)) for _, values in series)
    return 1.15 * limit if limit > 0 else 1.0


def plot_residual_scatter(
    x: ArrayLike,
    panels: Mapping[str, ArrayLike],
    *,
    groups: Mapping[str, ArrayLike] | None = None,
    xlabel: str = "x",
    ylabel: str = "residual y - yhat",
    title: str = "",
    scale: float = 1.0,
    bins: int = 40,
    logx: bool = False,
    axes: "Sequence[Axes] | None" = None,
) -> np.ndarray:
    """Residuals against a variable `x` (input, rate, ...): one of `axes` per entry
    of `panels` ({title: residual}, e.g. before and after a refit; None: a new
    figure of them, on shared axes). Returns the Axes.

    `groups` ({label: boolean mask}) splits the samples, e.g. into the ascending and
    descending branches; without it all samples form one group. Each group is drawn
    as faint points plus its binned mean (`bins` bins of x) as a bold line, so a
    systematic residual of a few noise sigmas stands out. `scale` multiplies the
    residuals; `logx=True` uses a logarithmic x-axis (non-positive x dropped).
    `title` is the figure's (its suptitle).
    """
    owner = "plot_residual_scatter"
    xs = _vector(x, "x", owner)
    series = _curves(panels, xs.shape[0], owner, scale)
    if groups is None:
        masks = [("", np.ones(xs.shape[0], bool))]
    else:
        masks = []
        for label, mask in groups.items():
            array = np.asarray(mask, bool)
            if array.shape != xs.shape:
                raise ValueError(
                    f"{owner}: group {label!r} has shape {array.shape} but x has "
                    f"{xs.shape}; pass one boolean per sample."
                )
            masks.append((str(label), array))
    drawn = _panels(
        axes,
        len(series),
        owner,
        "one per entry of panels",
        height=2.0 + 2.6 * len(series),
        sharex=True,
    )
    limit = _robust_limit(series)
    for axis, (name, values) in zip(drawn, series):
        for index, (label, mask) in enumerate(masks):
            keep = mask & (xs > 0) if logx else mask
            if not keep.any():
                continue
            color = f"C{index}"
            axis.scatter(
                xs[keep],
                values[keep],
                s=2.0,
                alpha=0.25,
                color=color,
                linewidths=0,
                rasterized=True,
            )
            if logx:
                cx, cy = _binned_mean(np.log10(xs[keep]), values[keep], bins)
                cx = 10.0**cx
            else:
                cx, cy = _binned_mean(xs[keep], values[keep], bins)
            axis.plot(
                cx,
                cy,
                color=color,
                linewidth=2.0,
                label=f"{label + ': ' if label else ''}binned mean",
            )
        axis.axhline(0.0, color="0.4", linewidth=0.8)
        axis.set_ylim(-limit, limit)
        axis.grid(True, alpha=0.3)
        axis.set_ylabel(ylabel)
        axis.set_title(name, fontsize="medium")
        axis.legend(loc="upper right", fontsize="small")
        if logx:
            axis.set_xscale("log")
    drawn[-1].set_xlabel(xlabel)
    if title:
        drawn[0].figure.suptitle(title)
    return _array(*drawn)


def plot_residual_time(
    t: ArrayLike,
    u: ArrayLike,
    residuals: Mapping[str, ArrayLike],
    *,
    ulabel: str = "input u",
    ylabel: str = "residual y - yhat",
    tlabel: str = "time t [s]",
    tunit: str = "s",
    title: str = "",
    scale: float = 1.0,
    window: float = 0.0,
    axes: "Sequence[Axes] | None" = None,
) -> np.ndarray:
    """Residuals against time under the input: `u(t)` on the first of `axes`, then
    one per entry of `residuals` ({label: y - yhat}; None: a new figure of them, on
    a shared time axis) with the raw residual faint and, when `window` (in the units
    of `t`, `tunit`) spans several samples, its centred moving average bold (the
    systematic part). `scale` multiplies the residuals; the y-axis holds 99.5 % of
    the samples. Returns the Axes.
    """
    owner = "plot_residual_time"
    time = _vector(t, "t", owner)
    inputs = _vector(u, "u", owner, time.shape[0])
    series = _curves(residuals, time.shape[0], owner, scale)
    drawn = _panels(
        axes,
        1 + len(series),
        owner,
        "the input, then one per residual",
        height=2.2 + 2.2 * len(series),
        sharex=True,
    )
    top = drawn[0]
    top.plot(time, inputs, color="0.3", linewidth=1.3)
    top.grid(True, alpha=0.3)
    top.set_ylabel(ulabel)
    if title:
        top.set_title(title)
    limit = _robust_limit(series)
    step = float(time[1] - time[0]) if time.shape[0] > 1 else 1.0
    width = max(1, min(int(round(window / step)), time.shape[0] // 5))
    for index, (axis, (label, values)) in enumerate(zip(drawn[1:], series)):
        color = f"C{index}"
        axis.plot(time, values, color=color, linewidth=0.5, alpha=0.35)
        if width > 1:
            smooth = np.convolve(values, np.ones(width) / width, mode="same")
            axis.plot(
                time,
                smooth,
                color=color,
                linewidth=1.8,
                label=f"moving average over {width * step:.3g} {tunit}".rstrip(),
            )
            axis.legend(loc="upper right", fontsize="small")
        axis.set_title(label, fontsize="medium")
        axis.axhline(0.0, color="0.4", linewidth=0.8)
        axis.set_ylim(-limit, limit)
        axis.grid(True, alpha=0.3)
        axis.set_ylabel(ylabel)
    drawn[-1].set_xlabel(tlabel)
    return _array(*drawn)


def _smoothed_spectrum(values: np.ndarray, rate: float, per_decade: int = 24):
    """Amplitude spectral density (Hann-windowed periodogram) averaged over
    log-spaced frequency bands, `per_decade` per decade: full resolution at the
    lowest frequencies (the excitation's harmonics), a smooth noise floor above."""
    x = values - values.mean()
    window = np.hanning(x.shape[0])
    spectrum = np.fft.rfft(x * window)
    freqs = np.fft.rfftfreq(x.shape[0], 1.0 / rate)
    density = 2.0 * np.abs(spectrum) ** 2 / (rate * np.sum(window**2))
    freqs, density = freqs[1:], density[1:]
    if freqs.size < 2:
        return freqs, np.sqrt(density)
    decades = np.log10(freqs[-1] / freqs[0])
    edges = freqs[0] * np.logspace(0, decades, max(2, int(decades * per_decade)) + 1)
    index = np.clip(np.searchsorted(edges, freqs, side="right") - 1, 0, None)
    counts = np.bincount(index)
    keep = counts > 0
    centres = np.bincount(index, weights=freqs)[keep] / counts[keep]
    power = np.bincount(index, weights=density)[keep] / counts[keep]
    return centres, np.sqrt(power)


def plot_spectrum(
    sample_rate: float,
    series: Mapping[str, ArrayLike],
    *,
    ylabel: str = "amplitude spectral density",
    title: str = "Spectrum",
    scale: float = 1.0,
    ax: "Axes | None" = None,
) -> "Axes":
    """Amplitude spectral density of every entry of `series` ({label: values
    sampled at `sample_rate` Hz}) on log-log axes, on `ax` (None: a new figure): a
    Hann-windowed periodogram averaged over log-spaced bands (24 per decade), so the
    lowest frequencies keep full resolution and the noise floor is smooth. `scale`
    multiplies the values first. White noise is a flat floor; structure a model
    leaves out shows as peaks or a rise above it. Returns the Axes.
    """
    owner = "plot_spectrum"
    rate = float(sample_rate)
    if not (np.isfinite(rate) and rate > 0):
        raise ValueError(f"{owner}: sample_rate must be positive, got {sample_rate!r}.")
    if not isinstance(series, Mapping) or not series:
        raise ValueError(f"{owner}: series must be a non-empty dict {{label: values}}.")
    lines = []
    for label, values in series.items():
        array = scale * _vector(values, f"series {label!r}", owner)
        lines.append((str(label), *_smoothed_spectrum(array, rate)))
    axis = _axis(ax)
    for index, (label, freqs, amplitude) in enumerate(lines):
        axis.loglog(
            freqs,
            amplitude,
            linestyle=_STYLES[min(index, len(_STYLES) - 1)],
            linewidth=1.4,
            marker="." if freqs.size < 200 else None,
            label=label,
        )
    axis.grid(True, which="both", alpha=0.3)
    axis.set_xlabel("frequency [Hz]")
    axis.set_ylabel(ylabel)
    if title:
        axis.set_title(title)
    axis.legend(loc="best", fontsize="small")
    return axis
