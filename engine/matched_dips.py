"""Dips of a profile whose noise is coloured: a matched filter against the measured noise.

A running-median residual compared with a threshold on its spread treats the noise as white.
The separated compliance of :mod:`engine.separation` is not: it is the difference of the
passes' long-wave inversion errors, strong at 10-40 m and weak at 3-6 m, while a soft zone's
dip holds most of its energy at its own length. The filter that best tells a known shape
``t`` from noise of spectrum ``P`` is ``T*(f) / P(f)`` (whiten, then correlate with the
whitened shape): it weighs each wavelength by how much the noise leaves of it. Details and
measurements: docs/method.md §10, "A detector for the compliance's coloured noise".
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray
from scipy import signal

from .detect import Dip, robust_sigma
from .intervals import true_runs

SPECTRUM_FLOOR = 0.02
"""Smallest noise density used, relative to its largest: outside the profile's band the
measured density is near zero and would turn the filter into an amplifier of round-off."""


def noise_spectrum(
    profile: NDArray[np.float64], step_m: float, segment_m: float
) -> tuple[NDArray[np.float64], NDArray[np.float64]] | None:
    """One-sided noise density of ``profile`` and its spatial frequencies (1/m).

    Welch's estimate over segments of ``segment_m`` (m, half overlapping) in every finite
    run at least that long, each run's estimate the median over its segments (the sparse
    dips of soft zones do not lift it), the runs averaged by length. None when no run is
    long enough for two segments.
    """
    nseg = int(round(segment_m / step_m))
    runs = [(a, b) for a, b in true_runs(np.isfinite(profile)) if b - a >= nseg]
    if nseg < 8 or sum(b - a for a, b in runs) < 2 * nseg:
        return None
    dens, lengths = [], []
    freq = np.zeros(0)
    for a, b in runs:
        freq, p = signal.welch(profile[a:b], fs=1.0 / step_m, nperseg=nseg, noverlap=nseg // 2,
                               average="median", detrend=False)  # fmt: skip
        dens.append(p)
        lengths.append(b - a)
    return freq, np.average(dens, axis=0, weights=lengths)


def matched_dips(
    chainage_m: NDArray[np.float64],
    profile: NDArray[np.float64],
    shapes: Sequence[tuple[float, NDArray[np.float64]]],
    noise_factor: float,
    segment_m: float,
    spread_window_m: float | None = None,
    local_share: float = 1.0,
) -> list[Dip] | None:
    """Dips of ``profile`` that a filter matched to a dip shape and to the profile's own
    noise finds more than ``noise_factor`` standard deviations deep.

    The strongest first; each dip found is subtracted (its shape at the filter's amplitude)
    before the next is looked for, and when none is left the noise's spectrum and spread
    are measured again on what is left and the search repeated while it finds more: the
    noise is the profile without its zones.

    Parameters
    ----------
    chainage_m : ndarray
        Regular grid, m.
    profile : ndarray
        The profile on it (any unit; NaN where not defined), its slow baseline removed.
    shapes : sequence of (length_m, template)
        The dips looked for: a zone length (m) and its dip shape on the grid's step, centred
        (odd length, positive down: the template is subtracted from a flat profile).
    noise_factor : float
        Threshold on each filter's output over its robust spread.
    segment_m : float
        Segment length of the noise spectrum's estimate, m (:func:`noise_spectrum`).
    spread_window_m : float or None
        Length (m) of the window of the output's running robust spread
        (:func:`local_spread`), which, times ``local_share``, replaces the profile's one
        spread where it is larger; None: the one spread everywhere.
    local_share : float
        The share of the running spread compared with the whole profile's.

    Returns
    -------
    list of Dip or None
        By chainage; each spans its best shape's length about the filter's peak, its depth
        the profile's value there (positive down). None when the profile is too short to
        measure its noise on (:func:`noise_spectrum`) or no shape is given.
    """
    setup = _setup(chainage_m, profile, shapes, segment_m, spread_window_m, local_share)
    if setup is None:
        return None
    y, runs, filters, stats, gains, scale = setup
    taken = np.zeros(y.size, dtype=bool)
    out: list[Dip] = []
    # strongest first; each dip found is taken out of the profile before the next is looked
    # for, so that a deep zone's filter side lobes (the whitened shape's autocorrelation,
    # ~25 m off) do not read as zones of their own. Rounds: when no dip is left over the
    # threshold, the noise is measured again on what is left and the search goes on while
    # a round finds one (with a few zones on a few hundred metres, their dips fill half the
    # spectrum's segments and the median of those holds their own band, which the filter
    # then weighs down as noise; once per round, not per dip, keeps a 10 km line's cost)
    while True:
        found = len(out)
        for _ in range(y.size):
            z = np.where(np.isfinite(stats) & ~taken, stats / scale, -np.inf)
            i, k = (int(v) for v in np.unravel_index(int(np.argmax(z)), z.shape))
            if z[i, k] <= noise_factor:
                break
            length, t = shapes[i]
            x = float(chainage_m[k])
            out.append(Dip(x - 0.5 * length, x + 0.5 * length, x, float(-profile[k])))
            # one dip per zone: the next peak must lie clear of this zone's extent and basin
            taken |= np.abs(chainage_m - x) <= 0.5 * length + 3.0
            amp = stats[i, k] / gains[i, k]
            h = t.size // 2
            lo, hi = max(k - h, 0), min(k + h + 1, y.size)
            y[lo:hi] -= amp * t[lo - k + h : hi - k + h]
            stats, gains = _filtered(y, runs, filters, len(shapes))
        if len(out) == found:
            break
        again = _setup(chainage_m, y, shapes, segment_m, spread_window_m, local_share)
        if again is None:  # not reached: y is defined where the profile is
            break
        _, runs, filters, stats, gains, scale = again
    out.sort(key=lambda d: d.start_m)
    return out


def matched_scores(
    chainage_m: NDArray[np.float64],
    profile: NDArray[np.float64],
    shapes: Sequence[tuple[float, NDArray[np.float64]]],
    segment_m: float,
    spread_window_m: float | None = None,
    local_share: float = 1.0,
) -> NDArray[np.float64] | None:
    """Per point, the largest over ``shapes`` of the matched filter's output over its robust
    spread (the statistic :func:`matched_dips` thresholds, before any dip is taken out);
    NaN where ``profile`` is not defined.

    Parameters and None as :func:`matched_dips`.
    """
    setup = _setup(chainage_m, profile, shapes, segment_m, spread_window_m, local_share)
    if setup is None:
        return None
    stats, scale = setup[3], setup[5]
    z = stats / scale
    out = np.full(z.shape[1], np.nan)
    defined = np.isfinite(z).any(axis=0)
    out[defined] = np.nanmax(z[:, defined], axis=0)
    return out


def _setup(
    chainage_m: NDArray[np.float64],
    profile: NDArray[np.float64],
    shapes: Sequence[tuple[float, NDArray[np.float64]]],
    segment_m: float,
    spread_window_m: float | None,
    local_share: float,
) -> (
    tuple[
        NDArray[np.float64],
        list[tuple[int, int]],
        list[tuple[int, list[NDArray[np.complex128]], list[float]]],
        NDArray[np.float64],
        NDArray[np.float64],
        NDArray[np.float64],
    ]
    | None
):
    """The profile (a copy), its runs, their filters, the filters' outputs and gains, and
    each shape's robust spread of its output per point (shapes x points, inf where zero: the
    larger of the whole profile's and, with ``spread_window_m``, the running one); None as
    :func:`matched_dips`."""
    step = float(chainage_m[1] - chainage_m[0])
    spec = noise_spectrum(profile, step, segment_m)
    if spec is None or not shapes:
        return None
    freq, dens = spec
    y = np.array(profile, dtype=float)
    runs = [(a, b) for a, b in true_runs(np.isfinite(y)) if b - a >= 8]
    longest = max(t.size for _, t in shapes)
    filters = [_run_filters(b - a, longest, step, freq, dens, shapes) for a, b in runs]
    stats, gains = _filtered(y, runs, filters, len(shapes))
    scale = np.array([robust_sigma(row) for row in stats])[:, None] * np.ones(y.size)
    if spread_window_m is not None:
        # the compliance's noise follows the rail's roughness, which varies along the line:
        # one spread over the profile sets the threshold too low where the rail is rougher
        local = np.array([local_spread(row, step, spread_window_m) for row in stats])
        scale = np.fmax(scale, local_share * local)
    return y, runs, filters, stats, gains, np.where(scale > 0, scale, np.inf)


def local_spread(x: NDArray[np.float64], step: float, window_m: float) -> NDArray[np.float64]:
    """Robust spread (:func:`engine.detect.robust_sigma`) of ``x`` (on a regular grid of
    ``step``, m) over a window of ``window_m`` (m) about each point, NaN where ``x`` is not
    defined or fewer than half the window's points are about every evaluated point.

    Evaluated every tenth of the window and interpolated linearly between: the spread
    changes over the window's length, not faster. A zone's dip in the output, a small part
    of the window, moves the median deviation little.
    """
    n = x.size
    half = max(int(round(0.5 * window_m / step)), 1)
    every = max(half // 5, 1)
    at = np.arange(0, n, every)
    if at[-1] != n - 1:
        at = np.append(at, n - 1)
    val = np.full(at.size, np.nan)
    for j, k in enumerate(at):
        w = x[max(k - half, 0) : k + half + 1]
        if np.count_nonzero(np.isfinite(w)) >= half:
            val[j] = robust_sigma(w)
    out = np.full(n, np.nan)
    ok = np.isfinite(val)
    if ok.any():
        out = np.interp(np.arange(n), at[ok], val[ok])
    return np.where(np.isfinite(x), out, np.nan)


def _run_filters(
    n: int,
    longest: int,
    step: float,
    freq: NDArray[np.float64],
    dens: NDArray[np.float64],
    shapes: Sequence[tuple[float, NDArray[np.float64]]],
) -> tuple[int, list[NDArray[np.complex128]], list[float]]:
    """For a run of ``n`` points: the FFT length, per shape the filter ``T*/P`` and its
    gain ``sum |T|^2 / P`` (the filter's output for the shape itself at unit depth)."""
    nfft = 2 ** math.ceil(math.log2(n + longest))
    f = np.fft.rfftfreq(nfft, step)
    p = np.maximum(np.interp(f, freq, dens), SPECTRUM_FLOOR * float(dens.max()))
    filt, gain = [], []
    for _, t in shapes:
        h = t.size // 2
        kernel = np.zeros(nfft)
        kernel[: t.size - h] = t[h:]
        kernel[nfft - h :] = t[:h]
        spec = np.fft.rfft(kernel)
        filt.append(np.conj(spec) / p)
        gain.append(float(np.fft.irfft(np.abs(spec) ** 2 / p, nfft)[0]))
    return nfft, filt, gain


def _filtered(
    y: NDArray[np.float64],
    runs: Sequence[tuple[int, int]],
    filters: Sequence[tuple[int, list[NDArray[np.complex128]], list[float]]],
    n_shapes: int,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Each shape's filter output along ``y`` (positive for a dip) and its gain, per point;
    NaN outside the runs."""
    stats = np.full((n_shapes, y.size), np.nan)
    gains = np.full((n_shapes, y.size), np.nan)
    for (a, b), (nfft, filt, gain) in zip(runs, filters, strict=True):
        spectrum = np.fft.rfft(y[a:b], nfft)
        for i in range(n_shapes):
            # a dip is the shape subtracted: its correlation is negative
            stats[i, a:b] = -np.fft.irfft(spectrum * filt[i], nfft)[: b - a]
            gains[i, a:b] = -gain[i]
    return stats, gains
